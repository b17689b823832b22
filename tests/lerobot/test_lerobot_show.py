"""robocal.workflows.lerobot.show: live normalised positions through the real SDK on a simulated arm."""

from __future__ import annotations

import pytest

from robocal.core.lerobot import MotorCalibration, normalize
from robocal.errors import UsageError
from robocal.workflows.lerobot import open_arm, read_positions, require_motors, restore, robot_spec

CALS = {
    n: MotorCalibration(i, 0, 0, 500, 3500)
    for i, n in enumerate(
        ("shoulder_pan", "shoulder_lift", "elbow_flex", "wrist_flex", "wrist_roll", "gripper"), 1
    )
}


def test_positions_are_lerobots_normalisation_of_present_position() -> None:
    spec = robot_spec("so101_follower")
    modes = ["degrees"] * 5 + ["range_0_100"]
    with open_arm(spec, "sim") as (bus, arm):
        assert arm is not None
        restore(bus, spec, CALS)
        arm.move({"shoulder_pan": 2047.5, "gripper": 2600})
        present = bus.sync_read("Present_Position", [m.motor_id for m in spec.motors])
        rows = list(read_positions(bus, spec, CALS, modes, samples=2))
    want = normalize([present[m.motor_id] for m in spec.motors], list(CALS.values()), modes)
    assert len(rows) == 2
    assert rows[0] == tuple(float(v) for v in want)
    # gripper 2600 in 500..3500 is 70 % of its range
    assert rows[0][5] == pytest.approx(70.0)


def test_a_calibration_without_every_motor_is_refused() -> None:
    spec = robot_spec("koch_leader")
    partial = {k: v for k, v in CALS.items() if k not in ("wrist_roll", "gripper")}
    with pytest.raises(UsageError, match=r"no entry for motor\(s\) wrist_roll, gripper"):
        require_motors(spec, partial)
