"""Paths of the Berkeley Humanoid Lite upstream files (tests/fixtures/lite, see its README)."""

from __future__ import annotations

from pathlib import Path

FIXTURES = Path(__file__).resolve().parents[1] / "fixtures" / "lite"
BIPED_URDF = FIXTURES / "berkeley_humanoid_lite_biped.urdf"
FULL_URDF = FIXTURES / "berkeley_humanoid_lite.urdf"
UPSTREAM_CAL = FIXTURES / "calibration.yaml"
REPLAY = FIXTURES / "biped_one_sided.csv"
BIMANUAL_URDF = Path(__file__).resolve().parents[2] / "examples" / "lite" / "lite_bimanual.urdf"

# Facts of HybridRobotics/Berkeley-Humanoid-Lite-Lowlevel @ 8b7f077 (robot/humanoid.py, scripts/calibrate_joints.py),
# written out here independently of the profile file so that a wrong profile fails the tests.
UPSTREAM_ORDER = [
    "left_hip_roll_joint", "left_hip_yaw_joint", "left_hip_pitch_joint", "left_knee_pitch_joint",
    "left_ankle_pitch_joint", "left_ankle_roll_joint", "right_hip_roll_joint", "right_hip_yaw_joint",
    "right_hip_pitch_joint", "right_knee_pitch_joint", "right_ankle_pitch_joint", "right_ankle_roll_joint",
]  # fmt: skip
UPSTREAM_IDS = [1, 3, 5, 7, 11, 13, 2, 4, 6, 8, 12, 14]
UPSTREAM_DIRS = [-1, 1, -1, -1, -1, 1, -1, 1, 1, 1, 1, 1]
UPSTREAM_SIDE = ["min", "max", "max", "min", "min", "min", "max", "min", "max", "min", "min", "max"]
UPSTREAM_IDEAL_DEG = [-10, 33.75, 56.25, 0, -45, -15, 10, -33.75, 56.25, 0, -45, 15]
URDF_ORDER = ["leg_" + n for n in UPSTREAM_ORDER]
