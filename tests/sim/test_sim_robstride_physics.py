"""Simulated Robstride motors with physics, driven through robocal's Robstride backend on python-can's virtual bus."""

from __future__ import annotations

import itertools
import math
import os
from collections.abc import Iterator
from contextlib import contextmanager

import pytest

from robocal.backends.robstride.bus import MotorSpec, RobstrideBus
from robocal.backends.robstride.protocol import Feedback, Param
from robocal.backends.robstride.sim import SimMotor, SimMotorBus
from robocal.backends.sim.physics import JointPlant, PlantParams, Scenario, SimClock, make_plant
from robocal.errors import CalibTimeoutError

pytest.importorskip("can")

_n = itertools.count()
OFFSET = 0.7  # hidden factory zero, rad
NOMINAL = PlantParams(stop_lower_rad=-1.0, stop_upper_rad=1.0, counts_per_rev=0)


@contextmanager
def rig(plant: JointPlant, direction: int = -1) -> Iterator[tuple[RobstrideBus, SimMotor, SimClock]]:
    clock = SimClock()
    motor = SimMotor(
        can_id=11,
        model="rs-00",
        direction=direction,
        factory_zero_rad=OFFSET,
        zero_sta=1,
        stop_lower_rad=-math.inf,
        stop_upper_rad=math.inf,
        plant=plant,
        clock=clock,
    )
    channel = f"robocal-phys-{os.getpid()}-{next(_n)}"
    with (
        SimMotorBus(channel, [motor]),
        RobstrideBus(channel, [MotorSpec("j", 11, "rs-00")], interface="virtual", timeout_s=2.0) as bus,
    ):
        yield bus, motor, clock


def hold(
    bus: RobstrideBus, clock: SimClock, motor_target: float, seconds: float, kp: float = 10.0
) -> Feedback:
    """MIT commands every 10 ms of simulated time; the last feedback."""
    fb = None
    for _ in range(round(seconds / 0.01)):
        fb = bus.mit_command("j", motor_target, 0.0, kp, 0.2, 0.0)
        clock.sleep(0.01)
    assert fb is not None
    return fb


def test_mit_contact_torque_is_kp_lag_clipped_at_limit_torque() -> None:
    plant = JointPlant(PlantParams(stiction_nm=0.0, coulomb_nm=0.0, counts_per_rev=0), q0_rad=0.9)
    with rig(plant) as (bus, _motor, clock):
        bus.enable("j")
        # joint q → motor angle −q + 0.7 (direction −1); target the joint at 1.05, past the stop at 1.0
        fb = hold(bus, clock, -1.05 + OFFSET, 2.0)
        q = plant.q_rad
        assert q == pytest.approx(1.0 + 10.0 * (1.05 - q) / 600.0, abs=1e-5)
        assert fb.torque_nm == pytest.approx(-10.0 * (1.05 - q), abs=0.01)  # motor frame: sign flipped
        assert fb.position_rad == pytest.approx(-q + OFFSET, abs=2e-4)  # 16 bits over ±4π
        bus.write_param("j", Param.LIMIT_TORQUE, 0.8)
        assert bus.read_param("j", Param.LIMIT_TORQUE) == pytest.approx(0.8)
        plant.peak_tau_motor_nm = 0.0
        fb = hold(bus, clock, -1.6 + OFFSET, 2.0)  # kp·lag = 6 N·m, clipped by limit_torque
        assert fb.torque_nm == pytest.approx(-0.8, abs=0.01)
        assert plant.q_rad == pytest.approx(1.0 + 0.8 / 600.0, abs=1e-5)
        assert plant.peak_tau_motor_nm <= 0.8 + 1e-6  # float32 parameter
        bus.stop("j")
        fb = hold(bus, clock, -1.6 + OFFSET, 0.1)  # reset mode: no torque whatever the command
        assert fb.torque_nm == 0.0 and fb.mode == 0
        assert clock.now() == pytest.approx(4.1 + 0.0005 * (400 + 10 + 4), abs=1e-9)


def test_stiction_holds_the_joint_below_breakaway() -> None:
    plant = make_plant(Scenario(stiction_ratio=0.8), NOMINAL, search_torque_nm=1.0, q0_rad=0.0)
    with rig(plant) as (bus, _motor, clock):
        bus.enable("j")
        for _ in range(100):  # 0.79 N·m feed-forward in the joint frame: no motion
            fb = bus.mit_command("j", 0.0, 0.0, 0.0, 0.0, -0.79)
            clock.sleep(0.01)
        assert plant.q_rad == 0.0 and fb.velocity_rad_s == 0.0
        for _ in range(10):
            fb = bus.mit_command("j", 0.0, 0.0, 0.0, 0.0, -0.85)
            clock.sleep(0.01)
        assert plant.q_rad > 0.01 and fb.velocity_rad_s < 0.0


def test_overload_fault_bit_cuts_torque_and_clears_with_stop() -> None:
    plant = make_plant(Scenario(overload_latch=True), NOMINAL, search_torque_nm=1.0, q0_rad=0.9)
    with rig(plant, direction=1) as (bus, _motor, clock):
        bus.enable("j")
        bus.write_param("j", Param.LIMIT_TORQUE, 1.0)
        fb = hold(bus, clock, 1.5 + OFFSET, 0.05, kp=5.0)  # 1 N·m (the limit), under the 0.1 s protection time
        assert fb.faults == 0 and fb.torque_nm == pytest.approx(1.0, abs=0.05)
        fb = hold(bus, clock, 1.5 + OFFSET, 0.1, kp=5.0)
        assert fb.faults == 0x10 and fb.torque_nm == 0.0
        bus.stop("j")  # without "clear faults" the latch stays
        bus.enable("j")
        assert hold(bus, clock, 1.5 + OFFSET, 0.05, kp=5.0).faults == 0x10
        bus.stop("j", clear_faults=True)
        bus.enable("j")
        fb = hold(bus, clock, 1.5 + OFFSET, 0.05, kp=5.0)
        assert fb.faults == 0 and fb.torque_nm > 0.9


def test_motor_stops_answering_at_the_stop_and_answers_again_once_released() -> None:
    plant = make_plant(Scenario(silent_at_stop=True), NOMINAL, search_torque_nm=1.0, q0_rad=0.9)
    with rig(plant, direction=1) as (bus, _motor, clock):
        bus.timeout_s = 0.3
        bus.enable("j")
        with pytest.raises(CalibTimeoutError, match="no reply"):
            hold(bus, clock, 1.5 + OFFSET, 1.0, kp=5.0)
        assert plant.q_rad > 1.0  # the commands were obeyed: it is in the stop
        with pytest.raises(CalibTimeoutError):
            bus.stop("j")  # heard (torque off), reply lost
        clock.sleep(0.2)
        fb = bus.stop("j")
        assert fb.mode == 0 and fb.torque_nm == 0.0


def test_seeded_runs_through_the_wire_are_identical() -> None:
    def run() -> list[float]:
        sc = Scenario(asymmetric_stops=True, gravity_nm=0.2)
        plant = make_plant(sc, PlantParams(noise_rad=1e-3), search_torque_nm=1.5, seed=9)
        out = []
        with rig(plant) as (bus, _m, clock):
            bus.enable("j")
            for i in range(150):
                out.append(bus.mit_command("j", OFFSET - 0.01 * i, 0.0, 10.0, 0.2, 0.0).position_rad)
                clock.sleep(0.01)
        return out

    assert run() == run()


@pytest.mark.slow
def test_lost_replies_are_applied_at_the_same_simulated_time_every_run() -> None:
    def run() -> list[float]:
        plant = make_plant(Scenario(silent_at_stop=True), NOMINAL, search_torque_nm=1.0, q0_rad=0.9)
        out = []
        with rig(plant, direction=1) as (bus, _motor, clock):
            bus.timeout_s = 0.05
            bus.enable("j")
            for _ in range(60):
                try:
                    out.append(bus.mit_command("j", 1.5 + OFFSET, 0.0, 5.0, 0.2, 0.0).position_rad)
                except CalibTimeoutError:
                    out.append(math.nan)
                clock.sleep(0.01)
            out.append(plant.q_rad)
        return out

    a, b = run(), run()
    assert math.isnan(a[-2])  # pressed into the stop: lost
    assert str(a) == str(b)  # nan-aware equality
