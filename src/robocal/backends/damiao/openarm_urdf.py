"""robocal's URDF of one OpenArm v10 arm: the joint names and limits calibration needs, a coarse chain for views.

The joints are named as openarm_description names them (``openarm_right_joint1`` … ``joint7``) and carry its v10
limits (``config/arm/v10/joint_limits.yaml``, the left arm's J1/J2 mirrored by the xacro's side transforms). The
gripper's motor angle is a revolute joint of its own, ``openarm_<side>_gripper_motor`` (−60°…0, closed at 0):
the description's ``finger_joint1`` is prismatic (0…0.044 m), driven by that motor through openarm_ros2's
linear map. The link offsets are a coarse stick figure (about 0.1-0.25 m per link), **not** the description's
kinematics, and the file has no masses (so no gravity model is taken from it). Shipped as
``robocal/data/openarm_v10_{right,left}.urdf``; a test keeps the files equal to :func:`openarm_urdf_text`.
"""

from __future__ import annotations

import math

from ...errors import UsageError
from .openarm import Side, openarm_joints

__all__ = ["GRIPPER_JOINT_SUFFIX", "openarm_urdf_joint", "openarm_urdf_text"]

GRIPPER_JOINT_SUFFIX = "gripper_motor"
"""The gripper motor's URDF joint: ``openarm_<side>_gripper_motor``."""

_AXES = ("0 0 1", "-1 0 0", "0 0 1", "0 1 0", "0 0 1", "1 0 0", "0 1 0", "0 0 1")
_OFFSETS = ("0 0 0.06", "0 0 0.03", "0 0 -0.06", "0 0 -0.25", "0 0 -0.1", "0 0 -0.15", "0 0 -0.04", "0 0 -0.08")
_VELOCITY = (16.754666, 16.754666, 5.445426, 5.445426, 20.943946, 20.943946, 20.943946, 20.943946)
_EFFORT = (40, 40, 27, 27, 7, 7, 7, 7)


def openarm_urdf_joint(side: Side, lerobot_name: str) -> str:
    """The URDF joint of LeRobot's motor ``lerobot_name`` (``joint_3`` → ``openarm_right_joint3``)."""
    if lerobot_name == "gripper":
        return f"openarm_{side}_{GRIPPER_JOINT_SUFFIX}"
    if lerobot_name.startswith("joint_") and lerobot_name[6:] in {str(i) for i in range(1, 8)}:
        return f"openarm_{side}_joint{lerobot_name[6:]}"
    raise UsageError(f"OpenArm has no motor {lerobot_name!r} (joint_1 … joint_7, gripper)")


def openarm_urdf_text(side: Side = "right") -> str:
    """The URDF of one arm (see the module docstring)."""
    joints = openarm_joints(side)
    prefix = f"openarm_{side}_"
    lines = [
        '<?xml version="1.0"?>',
        f"<!-- robocal's OpenArm v10 {side} arm: joint names and limits of openarm_description v10 (rad); "
        "coarse link offsets, no masses -->",
        f'<robot name="openarm_v10_{side}">',
        f'  <link name="{prefix}link0"/>',
    ]
    parent = f"{prefix}link0"
    for i, j in enumerate(joints):
        name = openarm_urdf_joint(side, j.name)
        child = f"{prefix}link{i + 1}" if j.name != "gripper" else f"{prefix}gripper_link"
        lines += [
            f'  <link name="{child}"/>',
            f'  <joint name="{name}" type="revolute">',
            f'    <parent link="{parent}"/>',
            f'    <child link="{child}"/>',
            f'    <origin xyz="{_OFFSETS[i]}" rpy="0 0 0"/>',
            f'    <axis xyz="{_AXES[i]}"/>',
            f'    <limit lower="{_fmt(j.stop_lower_rad)}" upper="{_fmt(j.stop_upper_rad)}" '
            f'velocity="{_VELOCITY[i]}" effort="{_EFFORT[i]}"/>',
            "  </joint>",
        ]
        parent = child
    lines.append("</robot>")
    return "\n".join(lines) + "\n"


def _fmt(rad: float) -> str:
    text = f"{rad:.6f}"
    return "0.000000" if math.isclose(rad, 0.0, abs_tol=5e-7) else text
