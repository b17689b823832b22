"""Names the tests of several systems expect, written once: the SO-101 joints, the UR links."""

from __future__ import annotations

SO101_JOINTS = ("shoulder_pan", "shoulder_lift", "elbow_flex", "wrist_flex", "wrist_roll", "gripper")
"""The SO-101 arm's joints (LeRobot's motor names, the URDF's joints), base first."""

UR_LINKS = ("shoulder", "upper_arm", "forearm", "wrist_1", "wrist_2", "wrist_3")
"""The six links of a UR kinematics YAML (ur_description), base first."""
