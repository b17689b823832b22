"""``openarm-ros2``: an OpenArm arm's measured ranges as ros2_control's ``joint_limits`` parameters.

The OpenArm's ROS 2 stack keeps no zero offset anywhere: openarm_ros2's ``OpenArm_v10HW`` takes each motor's
radians as the joint position (J1-J7) and maps the gripper motor linearly onto ``openarm_<side>_finger_joint1``
(motor 0 rad = 0 m closed, motor −1.0472 rad = 0.044 m open); its ros2_control xacro passes only the CAN
interface, prefix, hand and CAN-FD flags, and openarm_description's URDF has no transmission. So, as for LeRobot,
the calibration ROS 2 reads is the zero stored **in the motor** (``robocal sweep --auto --write-zero``), and what a
file can add is the range measured between the stops.

This format is that range in the keys ros2_control's ``joint_limits`` package reads (``joint_limits.<joint>.
has_position_limits`` / ``min_position`` / ``max_position``; MoveIt's ``joint_limits.yaml`` reads the same keys):
radians for J1-J7 in the joint frame, metres for the finger joint, six decimals rounded inward, joints named as
openarm_description names them. A ``<node>: ros__parameters: joint_limits:`` file reads too. As a joint map it
says "offset 0, direction +1" for every joint; the writer refuses a calibration whose offsets are not zero.
"""

from __future__ import annotations

import math
import re
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np

from ...core.jointmap import RobotCalibration
from ...core.profile import RobotProfile
from ...errors import FileFormatError, InvalidCalibrationError
from ...fileio import atomic_write_text
from .._numbers import parse_finite
from ..urdf import UrdfModel
from ._base import CalibrationFile, Content, FormatSpec, Traits, yaml_data
from .openarm_lerobot import ZERO_TOL_RAD

__all__ = ["FINGER_OPEN_M", "GRIPPER_OPEN_RAD", "SPEC", "finger_m", "gripper_rad"]

FINGER_OPEN_M = 0.044
"""openarm_ros2 ``GRIPPER_JOINT_0_POSITION``: the finger joint's open position, m."""
GRIPPER_OPEN_RAD = -1.0472
"""openarm_ros2 ``GRIPPER_MOTOR_1_RADIANS``: the gripper motor's reading when open, rad."""
_GRIPPER = re.compile(r"^openarm_(?:(left|right)_)?gripper_motor$")
_FINGER = re.compile(r"^openarm_(?:(left|right)_)?finger_joint1$")
_DECIMALS = 1e6
HEADER = (
    "# OpenArm joint limits measured by robocal (ros2_control joint_limits parameters; MoveIt reads the same keys).\n"
    "# Positions are against the zero stored in each motor (openarm_ros2 reads motor radians directly): rad for\n"
    "# joint1-7, metres for finger_joint1 (motor 0 rad = 0 m, -1.0472 rad = 0.044 m). In a node's parameter file,\n"
    "# nest it under <node>: ros__parameters:.\n"
)


def finger_m(motor_rad: float) -> float:
    """The finger joint's position for a gripper motor reading (openarm_ros2 ``motor_radians_to_joint``)."""
    return FINGER_OPEN_M * (motor_rad / GRIPPER_OPEN_RAD)


def gripper_rad(finger: float) -> float:
    """The gripper motor reading for a finger joint position (openarm_ros2 ``joint_to_motor_radians``)."""
    return (finger / FINGER_OPEN_M) * GRIPPER_OPEN_RAD


def _ros_name(joint: str) -> str:
    m = _GRIPPER.match(joint)
    if m is None:
        return joint
    return f"openarm_{m.group(1)}_finger_joint1" if m.group(1) else "openarm_finger_joint1"


def _gripper_name(finger: str, profile: RobotProfile | None, urdf: UrdfModel | None) -> str:
    """The gripper motor's joint for the ROS finger joint: the profile's ``gripper``, else by the OpenArm's naming."""
    if profile is not None:
        for j in profile.joints:
            if j.upstream_name == "gripper":
                return j.name
    m = _FINGER.match(finger)
    assert m is not None
    return f"openarm_{m.group(1)}_gripper_motor" if m.group(1) else "openarm_gripper_motor"


def _limits_table(data: Any) -> Mapping[Any, Any] | None:
    """The ``joint_limits`` mapping: at the top, or under one node's ``ros__parameters`` (None: neither)."""
    if not isinstance(data, Mapping):
        return None
    table = data.get("joint_limits")
    if table is None and len(data) == 1:
        params = next(iter(data.values()))
        if isinstance(params, Mapping) and isinstance(params.get("ros__parameters"), Mapping):
            table = params["ros__parameters"].get("joint_limits")
    return table if isinstance(table, Mapping) else None


def read(
    path: Path, *, urdf: UrdfModel | None = None, profile: RobotProfile | None = None, parsed_yaml: Any = None,
    **_: Any,
) -> CalibrationFile:
    """Read the joints with position limits as a joint map (offset 0, direction +1) with their ranges."""
    source = str(path)
    table = _limits_table(yaml_data(path, parsed_yaml))
    if table is None:
        raise FileFormatError(f"{source}: no 'joint_limits' mapping (ros2_control joint_limits parameters)")
    ranges: dict[str, tuple[float, float]] = {}
    for name, entry in table.items():
        where = f"{source}: joint {name!r}"
        if not isinstance(entry, Mapping):
            raise FileFormatError(f"{where}: expected a mapping")
        if "min_position" not in entry and "max_position" not in entry:
            continue  # velocity / acceleration limits only (MoveIt's own file): no range here
        if entry.get("has_position_limits") is not True:
            raise FileFormatError(f"{where}: min_position/max_position need has_position_limits: true")
        for key in ("min_position", "max_position"):
            if key not in entry:
                raise FileFormatError(f"{where}: missing key {key}")
        lo = parse_finite(entry["min_position"], where, "min_position")
        hi = parse_finite(entry["max_position"], where, "max_position")
        if not lo < hi:
            raise FileFormatError(f"{where}: min_position {lo} is not below max_position {hi}")
        joint = str(name)
        if _FINGER.match(joint):
            joint = _gripper_name(joint, profile, urdf)
            lo, hi = gripper_rad(hi), gripper_rad(lo)
        if joint in ranges:
            raise FileFormatError(f"{where}: names joint {joint} twice")
        ranges[joint] = (lo, hi)
    if not ranges:
        raise FileFormatError(f"{source}: no joint has min_position/max_position")
    joints = list(ranges)
    cal = RobotCalibration(joints, np.ones(len(joints)), np.zeros(len(joints)))
    return CalibrationFile(cal, {}, "openarm-ros2", source, (), ranges)


def _number(x: float) -> str:
    text = f"{x:.6f}"
    return "0.0" if float(text) == 0.0 else text


def _inward(lo: float, hi: float) -> tuple[float, float]:
    """Six decimals, rounded inward; a value within 1e-9 of six decimals is that value."""
    return math.ceil(lo * _DECIMALS - 1e-3) / _DECIMALS, math.floor(hi * _DECIMALS + 1e-3) / _DECIMALS


def dumps(cf: CalibrationFile, urdf: UrdfModel | None) -> str:
    """The file's text (see the module docstring); every joint of ``cf`` must be at its motor's zero."""
    cal = cf.calibration
    off = [
        f"{n} ({math.degrees(h):+.3f}°)"
        for n, d, h in zip(cal.joint_names, cal.direction, cal.homing_offset, strict=True)
        if abs(h) > ZERO_TOL_RAD or d != 1.0
    ]
    if off:
        raise InvalidCalibrationError(
            "format openarm-ros2 holds no offsets (openarm_ros2 reads each Damiao motor against its own zero); "
            f"joints {', '.join(off)} are not at the motor's zero or not direction +1: store the zeros in the "
            "motors first (robocal sweep --auto --write-zero)"
        )
    lines = [HEADER.rstrip("\n"), "joint_limits:"]
    for joint in cal.joint_names:
        if joint in cf.ranges_rad:
            lo, hi = cf.ranges_rad[joint]
        elif urdf is not None and joint in urdf.joint_names:
            lo, hi = urdf.limits(joint)
        else:
            raise InvalidCalibrationError(
                f"format openarm-ros2 needs a range for joint {joint}: none was measured and no URDF gives its "
                "limits (pass --urdf)"
            )
        name = _ros_name(joint)
        if name != joint:
            lo, hi = finger_m(hi), finger_m(lo)
        lo, hi = _inward(lo, hi)
        lines += [
            f"  {name}:",
            "    has_position_limits: true",
            f"    min_position: {_number(lo)}",
            f"    max_position: {_number(hi)}",
        ]
    return "\n".join(lines) + "\n"


def write(
    path: Path, cf: CalibrationFile, urdf: UrdfModel | None, profile: RobotProfile | None = None, **_: Any
) -> None:
    """Write the file atomically (validated first)."""
    atomic_write_text(path, dumps(cf, urdf))


def sniff(content: Content) -> bool:
    """A YAML ``joint_limits`` mapping (top level or one node's parameters) with at least one ``min_position``."""
    if content.kind != "yaml":
        return False
    table = _limits_table(content.data)
    return table is not None and any(isinstance(v, Mapping) and "min_position" in v for v in table.values())


SPEC = FormatSpec("openarm-ros2", read, write, sniff, sniff_rank=1, suffixes=(), traits=Traits.SELF_CONTAINED)
