"""Host-loss watchdogs (issue 26 item 2): armed before the first motion, disarmed after, modelled by the simulators.

Robstride ``canTimeout`` (0x7028, 20000 = 1 s): a motor in run mode that hears no frame for that long enters reset
mode. Dynamixel X ``Bus_Watchdog`` (98, 20 ms units): with torque on and no instruction packet for that long the
servo stops, ``Bus_Watchdog`` reads −1 and goal writes are refused (Data Range error) until it is written 0.
Feetech STS servos have none. All on the simulated clock: the trip lands at exactly the last frame + the time.
"""

from __future__ import annotations

import itertools
import math
import os
from collections.abc import Iterator
from contextlib import contextmanager
from typing import Any

import pytest

from robocal.backends.robstride.bus import MotorSpec, RobstrideBus
from robocal.backends.robstride.joint_driver import (
    MAX_LAG_RAD,
    WATCHDOG_S,
    RobstrideJointDriver,
    RobstrideWatchdogError,
)
from robocal.backends.robstride.protocol import Param
from robocal.backends.robstride.sim import SimMotor, SimMotorBus
from robocal.backends.sim.physics import JointPlant, PlantParams, SimClock
from robocal.core.stop_search import Command
from robocal.errors import DeviceError

pytest.importorskip("can")
pytestmark = pytest.mark.timeout(300)

_n = itertools.count()


@contextmanager
def lite_rig(n: int = 1) -> Iterator[tuple[RobstrideBus, list[SimMotor], SimClock]]:
    clock = SimClock()
    motors = [
        SimMotor(
            can_id=11 + i,
            model="rs-05",
            stop_lower_rad=-math.inf,
            stop_upper_rad=math.inf,
            plant=JointPlant(PlantParams(stop_lower_rad=-1.0, stop_upper_rad=1.0, counts_per_rev=0)),
            clock=clock,
        )
        for i in range(n)
    ]
    channel = f"robocal-wd-{os.getpid()}-{next(_n)}"
    specs = [MotorSpec(f"j{i}", 11 + i, "rs-05") for i in range(n)]
    with SimMotorBus(channel, motors), RobstrideBus(channel, specs, interface="virtual", timeout_s=2.0) as bus:
        yield bus, motors, clock


def test_robstride_can_timeout_stops_a_motor_exactly_when_the_host_falls_silent() -> None:
    with lite_rig() as (bus, (motor,), clock):
        assert bus.arm_watchdog("j0", 0.5) == 0.0  # off before (the factory setting)
        assert motor.can_timeout == 10000  # 20000 = 1 s
        assert bus.read_param("j0", Param.CAN_TIMEOUT) == 10000
        bus.enable("j0")
        for _ in range(40):  # frames every 10 ms: the watchdog never trips
            bus.mit_command("j0", 0.9, 0.0, 2.0, 0.05, 0.0)
            clock.sleep(0.01)
        assert motor.mode == 2 and motor.watchdog_trips == []
        last = motor.last_rx_s
        assert last is not None and motor.plant is not None and abs(motor.plant.tau_motor_nm) > 0
        clock.sleep(2.0)  # the host is gone: no frame for 2 s of simulated time
        motor.sync()  # what the firmware does on its own (the next frame would find it so); no frame is in flight
        assert motor.mode == 0  # reset mode: limp
        assert motor.watchdog_trips == [(last, pytest.approx(last + 0.5, abs=1e-9))]
        assert motor.plant.t_s == pytest.approx(clock.now(), abs=1e-3)
        assert motor.plant.tau_motor_nm == 0.0  # after the trip the plant runs limp
        bus.disarm_watchdog("j0")
        assert motor.can_timeout == 0


def test_the_driver_arms_before_moving_and_disarms_when_limp() -> None:
    with lite_rig() as (bus, (motor,), clock):
        drv = RobstrideJointDriver(bus, "j0", 1, 0.4, MAX_LAG_RAD, clock)
        assert motor.can_timeout == 0
        drv.execute(Command("drive", 0.1, 0.0, 0.4))
        assert motor.can_timeout == round(WATCHDOG_S * 20000) and motor.mode == 2
        drv.limp()
        assert motor.can_timeout == 0 and motor.mode == 0  # disarmed, back to what it was


def test_a_host_held_up_past_the_watchdog_is_a_device_fault_and_the_motor_already_stopped() -> None:
    with lite_rig() as (bus, (motor,), clock):
        drv = RobstrideJointDriver(bus, "j0", 1, 0.4, MAX_LAG_RAD, clock)
        for k in range(20):
            drv.execute(Command("drive", 0.01 * k, 0.0, 0.4))
        clock.sleep(1.0)  # robocal descheduled for 1 s (simulated): the motor stopped itself after 0.5 s
        with pytest.raises(RobstrideWatchdogError, match="left run mode on its own") as info:
            drv.execute(Command("drive", 0.2, 0.0, 0.4))
        assert isinstance(info.value, DeviceError) and info.value.exit_code == 3
        assert len(motor.watchdog_trips) == 1
        last, at = motor.watchdog_trips[0]
        assert at - last == pytest.approx(0.5, abs=1e-9)
        drv.limp()
        assert motor.can_timeout == 0


def test_a_reread_after_the_watchdog_tripped_is_a_fault_not_a_clear_and_enable() -> None:
    """The search re-reads after a lost reply or an overload; a motor whose ``canTimeout`` tripped meanwhile (robocal
    held up) stopped on its own and may have dropped. Before, the re-read's type-4 stop with fault clear and the
    enable after it put it back in run mode as if it had held its command (only the search's 0.5 s reading-gap
    bound caught it); now the re-read asks the motor first, and its reply (reset mode) ends the run."""
    with lite_rig() as (bus, (motor,), clock):
        drv = RobstrideJointDriver(bus, "j0", 1, 0.4, MAX_LAG_RAD, clock)
        for k in range(20):
            drv.execute(Command("drive", 0.01 * k, 0.0, 0.4))
        clock.sleep(1.0)  # held up for 1 s: the motor stopped itself after 0.5 s
        enables = motor.requests.get(3, 0)
        with pytest.raises(RobstrideWatchdogError, match="left run mode on its own"):
            drv.execute(Command("reread", 0.2, 0.0, 0.4))
        assert motor.mode == 0 and len(motor.watchdog_trips) == 1
        assert motor.requests.get(3, 0) == enables  # never enabled again (type 3)
        assert motor.requests.get(4, 0) == 0  # and nothing cleared (type 4)
        drv.limp()
        assert motor.can_timeout == 0


def test_a_reread_of_a_latched_overload_clears_it_and_drives_on() -> None:
    with lite_rig() as (bus, (motor,), clock):
        drv = RobstrideJointDriver(bus, "j0", 1, 0.4, MAX_LAG_RAD, clock)
        for k in range(5):
            drv.execute(Command("drive", 0.01 * k, 0.0, 0.4))
        assert motor.plant is not None
        motor.plant.latched = True  # the firmware's overload latch (fault bit 20, torque cut)
        s = drv.execute(Command("drive", 0.05, 0.0, 0.4))
        assert s.overload
        s = drv.execute(Command("reread", 0.05, 0.0, 0.4))
        assert s.ok and not s.overload and motor.mode == 2 and not motor.plant.latched
        assert motor.requests.get(4, 0) == 1  # one stop with fault clear
        drv.limp()


def test_a_joint_holding_its_pose_is_kept_alive_while_another_is_searched() -> None:
    with lite_rig(2) as (bus, (held, searched), clock):
        hold = RobstrideJointDriver(bus, "j0", 1, 0.4, MAX_LAG_RAD, clock)
        move = RobstrideJointDriver(bus, "j1", 1, 0.4, MAX_LAG_RAD, clock)
        hold.execute(Command("hold", 0.2, 0.0, 0.4))
        for k in range(300):  # 3 s of the other joint's search: the held joint gets its last command again
            move.execute(Command("drive", 0.002 * k, 0.0, 0.4))
        assert held.mode == 2 and held.watchdog_trips == [] and searched.watchdog_trips == []
        assert held.last_command is not None and held.last_command[0] == pytest.approx(0.2, abs=1e-3)
        hold.limp()
        move.limp()
        assert held.can_timeout == searched.can_timeout == 0


# ------------------------------------------------------------------------------------------ Dynamixel X
def test_dynamixel_bus_watchdog_stops_the_servo_and_refuses_goals_until_cleared() -> None:
    from robocal.workflows.lerobot import robot_spec
    from robocal.workflows.lerobot.auto import auto_section
    from robocal.workflows.lerobot.auto_sim import open_auto_arm

    spec = robot_spec("koch_follower")
    with open_auto_arm(spec, "sim?transport=inproc", auto_section("koch_follower")) as arm:
        bus, clock, servo = arm.bus, arm.clock, arm.sim.servo("elbow_flex")
        assert bus.read("Bus_Watchdog", 3) == 0  # off as shipped
        bus.arm_watchdog([3], 0.5)
        assert bus.read("Bus_Watchdog", 3) == 25  # 20 ms units
        bus.write("Operating_Mode", 3, 5)
        bus.write("Torque_Enable", 3, 1)
        start = bus.read("Present_Position", 3)
        for k in range(50):  # goals every 10 ms: no trip
            bus.sync_write("Goal_Position", {3: start + 4 * k})
            clock.sleep(0.01)
        assert servo.watchdog_trips == []
        last = servo.watchdog_rx_s
        assert last is not None
        clock.sleep(1.5)  # the host is gone
        assert bus.read("Bus_Watchdog", 3) == -1  # the next packet finds it tripped, at last + 0.5 s exactly
        assert servo.watchdog_trips == [(last, pytest.approx(last + 0.5, abs=1e-9))]
        held = bus.read("Present_Position", 3)
        assert bus.read("Goal_Position", 3) == held  # stopped: the goal is where the joint is
        assert bus.read("Torque_Enable", 3) == 1  # it holds (the e-Manual: it stops, torque stays on)
        with pytest.raises(DeviceError, match="Goal_Position"):
            bus.write("Goal_Position", 3, held + 300)  # refused: Data Range error
        bus.sync_write("Goal_Position", {3: held + 300})  # a SYNC_WRITE is silently refused the same way
        clock.sleep(0.3)
        assert abs(bus.read("Present_Position", 3) - held) <= 2 and bus.read("Goal_Position", 3) == held
        bus.disarm_watchdog([3])
        assert bus.read("Bus_Watchdog", 3) == 0
        bus.write("Goal_Position", 3, held + 100)  # accepted again
        assert bus.read("Goal_Position", 3) == held + 100


def test_lerobot_auto_arms_the_bus_watchdog_while_searching_and_restores_it() -> None:
    from robocal.workflows.lerobot import robot_spec
    from robocal.workflows.lerobot.auto import AutoCalibrationRequest, auto_calibrate, auto_section
    from robocal.workflows.lerobot.auto_sim import open_auto_arm

    spec = robot_spec("koch_follower")
    section = auto_section("koch_follower")
    seen: list[int] = []

    class View:
        def joint_start(self, name: str, cap_nm: float, speed_rad_s: float) -> None:
            pass

        def sample(self, name: str, phase: str, side: str, sample: Any) -> None:
            if len(seen) < 3:
                seen.append(arm.sim.servo("gripper").get_reg("Bus_Watchdog"))

        def joint_done(self, outcome: Any) -> None:
            pass

    asked: list[Any] = []

    def confirm(names: Any, caps: Any) -> bool:
        asked.append(caps)
        return True

    with open_auto_arm(spec, "sim?seed=1&transport=inproc", section) as arm:
        res = auto_calibrate(
            arm.bus,
            AutoCalibrationRequest(
                spec,
                section,
                joints=["gripper"],
                path=None,
            ),
            clock=arm.clock,
            view=View(),
            confirm_start=confirm,
        )
        assert res.auto["gripper"].ok
        assert asked[0].host_loss == (
            "If robocal is killed or the cable is pulled, each moving servo's Bus Watchdog stops it within 0.5 s."
        )
        assert seen == [25, 25, 25]  # armed (0.5 s) before the first motion
        assert {m.name: arm.sim.servo(m.name).get_reg("Bus_Watchdog") for m in spec.motors} == dict.fromkeys(
            spec.motor_names, 0
        )  # disarmed after
        assert arm.sim.servo("gripper").watchdog_trips == []


def test_the_feetech_prompt_says_there_is_no_watchdog() -> None:
    from robocal.workflows.lerobot.auto import HOST_LOSS

    assert HOST_LOSS["feetech"].startswith("Feetech STS servos have no host-loss watchdog")
    assert "until the power is cut" in HOST_LOSS["feetech"]
