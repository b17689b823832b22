"""The simulated OpenArm v10 on python-can's virtual bus, driven through DamiaoBus (judged by the plants' state)."""

from __future__ import annotations

import itertools
import math
import time
from collections.abc import Iterator

import pytest

from robocal.backends.damiao.bus import DamiaoBus
from robocal.backends.damiao.faults import DamiaoRotorOverTempError
from robocal.backends.damiao.openarm import OPENARM_V10, SimOpenArm, openarm_joints
from robocal.backends.damiao.protocol import MitCommand
from robocal.backends.damiao.tables import State
from robocal.backends.sim.scenarios import Scenario
from robocal.errors import CalibTimeoutError, UsageError

_counter = itertools.count()
LSB_RAD = 25.0 / 65535 + math.tau / 16384  # one state-frame step plus one 14-bit encoder count


def _channel() -> str:
    return f"dm-openarm-{next(_counter)}"


@pytest.fixture
def arm() -> Iterator[tuple[SimOpenArm, DamiaoBus]]:
    ch = _channel()
    sim = SimOpenArm(ch, seed=7).start()
    bus = DamiaoBus(ch, sim.motor_specs(), interface="virtual", fd=True, timeout_s=5.0, allow_motion=True)
    try:
        yield sim, bus
    finally:
        bus.close()
        sim.stop()


def test_the_joint_table_is_the_openarm_v10s() -> None:
    assert [(j.name, j.esc_id, j.mst_id, j.model) for j in OPENARM_V10] == [
        ("joint_1", 0x01, 0x11, "DM8009"),
        ("joint_2", 0x02, 0x12, "DM8009"),
        ("joint_3", 0x03, 0x13, "DM4340"),
        ("joint_4", 0x04, 0x14, "DM4340"),
        ("joint_5", 0x05, 0x15, "DM4310"),
        ("joint_6", 0x06, 0x16, "DM4310"),
        ("joint_7", 0x07, 0x17, "DM4310"),
        ("gripper", 0x08, 0x18, "DM4310"),
    ]
    stops = [
        (round(math.degrees(j.stop_lower_rad)), round(math.degrees(j.stop_upper_rad))) for j in OPENARM_V10
    ]
    assert stops == [(-80, 200), (-10, 190), (-90, 90), (0, 140), (-90, 90), (-45, 45), (-90, 90), (-60, 0)]
    left = openarm_joints("left")
    assert [
        (round(math.degrees(j.stop_lower_rad)), round(math.degrees(j.stop_upper_rad))) for j in left[:3]
    ] == [
        (-200, 80),
        (-190, 10),
        (-90, 90),
    ]
    assert [j.peak_torque_nm for j in OPENARM_V10[::2]] == [40.0, 27.0, 7.0, 7.0]
    with pytest.raises(UsageError, match="OpenArm side 'up'; expected 'right' or 'left'"):
        openarm_joints("up")  # type: ignore[arg-type]


def test_every_motor_answers_and_a_factory_zero_is_not_the_joints(arm: tuple[SimOpenArm, DamiaoBus]) -> None:
    sim, bus = arm
    states = bus.refresh()
    assert list(states) == [j.name for j in OPENARM_V10]
    assert bus.range_sources == dict.fromkeys(states, "registers")
    for name, state in states.items():
        truth = sim.joint_rad(name) + sim.zero_error_rad(name)
        assert state.position_rad == pytest.approx(truth, abs=LSB_RAD), name
        assert -math.pi <= sim.zero_error_rad(name) < math.pi + 0.1
    assert sum(abs(sim.zero_error_rad(n)) > 0.1 for n in states) >= 6  # seeded factory zeros are arbitrary


def test_a_zeroed_arm_reads_the_joint_angles() -> None:
    ch = _channel()
    sim = SimOpenArm(ch, seed=1, zeroed=True, side="left")
    with sim, DamiaoBus(ch, sim.motor_specs(), interface="virtual", timeout_s=5.0) as bus:
        states = bus.refresh()
        truth = sim.joint_angles_rad()
    assert truth["joint_4"] == pytest.approx(math.radians(2.0), abs=1e-3)
    assert truth["gripper"] == pytest.approx(math.radians(-2.0), abs=1e-3)
    for name, state in states.items():
        assert state.position_rad == pytest.approx(truth[name], abs=LSB_RAD), name


def test_driving_joint_4_into_its_metal_stop_stops_it_at_140_degrees(
    arm: tuple[SimOpenArm, DamiaoBus],
) -> None:
    sim, bus = arm
    start = bus.refresh(["joint_4"])["joint_4"].position_rad
    bus.enable(["joint_4"])
    for i in range(1, 501):  # 0.6 rad/s toward the stop and 10° past it (kp 40: ~7 N·m into the stop)
        target = start + min(i * 0.006, math.radians(150))
        bus.mit("joint_4", MitCommand(target, 0.0, 40.0, 1.0, 0.0))
        sim.clock.sleep(0.01)
    assert sim.joint_rad("joint_4") == pytest.approx(math.radians(140), abs=math.radians(0.5))
    state = bus.read_state("joint_4")
    assert state.position_rad - start == pytest.approx(
        sim.joint_rad("joint_4") - math.radians(2), abs=3 * LSB_RAD
    )
    assert state.torque_nm > 2.0  # pressing into the stop (and holding the forearm against gravity)
    bus.disable(["joint_4"])


def test_gravity_pulls_a_limp_shoulder_back_to_hanging(arm: tuple[SimOpenArm, DamiaoBus]) -> None:
    sim, bus = arm
    sim.set_joint("joint_2", math.radians(60))
    for _ in range(300):
        bus.limp(["joint_2"])
        sim.clock.sleep(0.01)
    assert abs(sim.joint_rad("joint_2")) < math.radians(5)


def test_a_power_cycle_aliases_joint_1_beyond_half_a_turn() -> None:
    ch = _channel()
    with SimOpenArm(ch, zeroed=True) as sim:
        sim.set_joint("joint_1", math.radians(190))
        with DamiaoBus(ch, sim.motor_specs(), interface="virtual", timeout_s=5.0) as bus:
            assert bus.read_state("joint_1").position_rad == pytest.approx(math.radians(190), abs=LSB_RAD)
            sim.power_cycle()
            assert bus.read_state("joint_1").position_rad == pytest.approx(math.radians(-170), abs=LSB_RAD)


def test_a_scenario_changes_only_its_joint() -> None:
    sim = SimOpenArm(_channel(), scenarios={"joint_6": Scenario(missing_stop="upper")})
    assert sim.plants["joint_6"].params.stop_upper_rad is None
    assert sim.plants["joint_5"].params.stop_upper_rad == pytest.approx(math.pi / 2)
    with pytest.raises(UsageError, match="no joint\\(s\\) joint_9 on the OpenArm"):
        SimOpenArm(_channel(), scenarios={"joint_9": Scenario()})


def test_a_realtime_arm_moves_with_the_wall_clock() -> None:
    ch = _channel()
    sim = SimOpenArm(ch, zeroed=True, realtime=True)
    with sim, DamiaoBus(ch, sim.motor_specs(), interface="virtual", timeout_s=5.0, allow_motion=True) as bus:
        bus.enable(["joint_5"])
        bus.mit("joint_5", MitCommand(0.5, 0.0, 20.0, 0.5, 0.0))
        deadline = time.monotonic() + 60.0  # a hang guard: the joint settles in ~0.5 s of simulated time
        while abs(sim.joint_rad("joint_5") - 0.5) > 0.01 and time.monotonic() < deadline:
            time.sleep(0.05)
        assert sim.joint_rad("joint_5") == pytest.approx(0.5, abs=0.01)
        assert sim.clock.now() > 0.05  # moved by the pacer: the ~25 frames sent add 0.2 ms each
        assert bus.read_state("joint_5").position_rad == pytest.approx(sim.joint_rad("joint_5"), abs=LSB_RAD)


def test_a_silenced_or_faulted_motor_fails_by_name() -> None:
    ch = _channel()
    sim = SimOpenArm(ch, zeroed=True)
    with sim, DamiaoBus(ch, sim.motor_specs(), interface="virtual", timeout_s=0.3) as bus:
        sim.silence("joint_3")
        with pytest.raises(CalibTimeoutError, match=r"no reply within 0.3 s from motor 'joint_3' \(ESC_ID 0x3"):
            bus.refresh()
        sim.silence("joint_3", silent=False)
        sim.inject_fault("gripper", State.ROTOR_OVER_TEMP)
        with pytest.raises(DamiaoRotorOverTempError, match=r"'gripper'.*rotor \(coil\) over-temperature"):
            bus.refresh()
        assert bus.clear_error("gripper").state == State.DISABLED
    assert sim.motors["gripper"].requests["clear error"] == 1 and sim.motors["joint_3"].requests["refresh"] == 1
