"""Shared values of the LeRobot tests."""

from __future__ import annotations

from pathlib import Path

from robocal.backends.sim.lerobot_arms import DEFAULT_TRUTH

LEGACY = (
    '{"homing_offset": [2048, 3072, 3072, -1024, -1024, 2048], "drive_mode": [1, 1, 1, 0, 0, 0], '
    '"start_pos": [2015, 3058, 3061, 1071, 1071, 2499], "end_pos": [-1008, -1963, -1966, 2141, 2143, 3144], '
    '"calib_mode": ["DEGREE", "DEGREE", "DEGREE", "DEGREE", "DEGREE", "LINEAR"], '
    '"motor_names": ["shoulder_pan", "shoulder_lift", "elbow_flex", "wrist_flex", "wrist_roll", "gripper"]}'
)
"""A legacy (2024) SO-100 calibration file as LeRobot wrote it (parallel arrays)."""


def calibrate_args(
    calibration_dir: Path, *extra: str, robot: str = "so101_follower", port: str = "sim", robot_id: str = "arm1"
) -> list[str]:
    """``lerobot calibrate --robot ROBOT --port PORT --id ID --calibration-dir DIR [extra…]``."""
    return ["lerobot", "calibrate", "--robot", robot, "--port", port, "--id", robot_id,
            "--calibration-dir", str(calibration_dir), *extra]  # fmt: skip

# A previous calibration in the simulated arms' EEPROM, different from what a sweep finds: rollbacks must restore it.
PREVIOUS = {
    "so101_follower": {
        n: {"Homing_Offset": -100 - i, "Min_Position_Limit": 500 + i, "Max_Position_Limit": 3500 - i}
        for i, n in enumerate(DEFAULT_TRUTH["so101_follower"])
    },
    "koch_leader": {
        n: {
            "Homing_Offset": -3000 + i,
            "Min_Position_Limit": 100 + i,
            "Max_Position_Limit": 3900 - i,
            "Drive_Mode": 0,
        }
        for i, n in enumerate(DEFAULT_TRUTH["koch_leader"])
    },
}
