"""Issue 26: a device lost before anything moved is given up after one silent round, not after every read's retries.

Before, a Koch or SO-101 whose cable was pulled at start-up paid the full retries of each read: the note about what
a previous run left changed read every motor (4 tries each, a Koch ~100 s in the fault harness at a 2 s reply
timeout) and then the snapshot's first read. Now the first read that fails with all its retries is followed by one
round of reads, one try each; when no motor answers, the command ends with :class:`DeviceGoneError` (exit 3) and one
line: the device is lost, nothing was moved or written (and, with a kept snapshot, how to restore it later).
Judged by the packets robocal sent and by the simulated servos' registers.
"""

from __future__ import annotations

import pytest

from robocal.backends.sim.lerobot_arms import SimArm
from robocal.errors import CalibTimeoutError, DeviceGoneError
from robocal.workflows.lerobot import open_bus, robot_spec
from robocal.workflows.lerobot.auto import snapshot_registers
from robocal.workflows.lerobot.guard import find_left_over
from robocal.workflows.motion.snapshot import SnapshotStore

from .guardlib import count_bus_calls

pytestmark = pytest.mark.timeout(300)

REGISTERS = ("Homing_Offset", "Min_Position_Limit", "Max_Position_Limit", "Torque_Enable", "Operating_Mode")


def _servo_state(arm: SimArm) -> dict[str, tuple[int, ...]]:
    return {m.name: tuple(arm.servo(m.name).get_reg(r) for r in REGISTERS) for m in arm.spec.motors}


@pytest.mark.parametrize("robot", ["so101_follower", "koch_follower"])
def test_a_lost_device_before_the_snapshot_is_given_up_after_one_round(robot: str) -> None:
    spec = robot_spec(robot)
    with SimArm(spec) as arm:
        was = _servo_state(arm)
        arm.bus.silent_ids.update(m.motor_id for m in spec.motors)
        bus = open_bus(spec, arm.port)
        calls = count_bus_calls(bus)
        try:
            with pytest.raises(DeviceGoneError) as info:
                snapshot_registers(bus, spec, ["gripper"])
        finally:
            bus.close()
        # the first read with its retries, then one round: a SYNC_READ (Koch) or nothing more than one read per
        # remaining motor, each sent once; no second read of any motor with retries
        assert calls[0][1] == 3 and all(retries == 0 for _what, retries in calls[1:]), calls
        assert len(calls) <= 1 + len(spec.motors), calls
        assert bus.retries == 3  # put back
        text = str(info.value)
        assert text.endswith(
            "the device is lost (no motor answered a whole round of reads) before anything was moved or written"
        ), text
        assert info.value.exit_code == 3 and "\n" not in text
        arm.bus.silent_ids.clear()
        assert _servo_state(arm) == was  # nothing written


def test_one_silent_motor_is_not_a_lost_device() -> None:
    """The others answer: the silent motor's own error (its retries), not "the device is lost"."""
    spec = robot_spec("so101_follower")
    with SimArm(spec) as arm:
        arm.bus.silent_ids.add(spec.motors[0].motor_id)
        bus = open_bus(spec, arm.port)
        try:
            with pytest.raises(CalibTimeoutError) as info:
                snapshot_registers(bus, spec, ["gripper"])
        finally:
            bus.close()
        assert not isinstance(info.value, DeviceGoneError)
        assert "the device is lost" not in str(info.value)


@pytest.mark.parametrize("robot", ["so101_follower", "koch_follower"])
def test_a_lost_device_with_a_kept_snapshot_is_given_up_after_one_round(robot: str) -> None:
    """What a previous run left changed is kept; the device is gone when the next command opens it."""
    spec = robot_spec(robot)
    with SimArm(spec) as arm:
        store = SnapshotStore(arm.port, "lerobot calibrate --auto")
        store.save(
            {m.name: {"Homing_Offset": arm.servo(m.name).get_reg("Homing_Offset") + 1} for m in spec.motors},
            robot=spec.name,
        )
        arm.bus.silent_ids.update(m.motor_id for m in spec.motors)
        bus = open_bus(spec, arm.port)
        calls = count_bus_calls(bus)
        try:
            with pytest.raises(DeviceGoneError) as info:
                find_left_over(bus, spec, arm.port)
        finally:
            bus.close()
        assert calls[0][1] == 3 and all(retries == 0 for _what, retries in calls[1:]), calls
        assert len(calls) <= 1 + len(spec.motors), calls
        text = str(info.value)
        assert "the device is lost (no motor answered a whole round of reads) before anything was moved" in text
        assert text.endswith(f"`robocal lerobot restore-previous --robot {robot} --port {arm.port}`"), text
        assert "a previous run (lerobot calibrate --auto)" in text
        # the kept snapshot stays for when the device is back
        arm.bus.silent_ids.clear()
        fresh = open_bus(spec, arm.port)
        try:
            left = find_left_over(fresh, spec, arm.port)
        finally:
            fresh.close()
        assert left is not None and len(left.differing) == len(spec.motors)
