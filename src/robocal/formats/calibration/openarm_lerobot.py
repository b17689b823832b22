"""``openarm-lerobot``: LeRobot 0.6.1's calibration file of an OpenArm arm (``openarm_follower`` / ``openarm_leader``).

LeRobot's ``OpenArmFollower.calibrate()`` writes ``draccus.dump(dict[str, MotorCalibration], indent=4)``: the eight
motors ``joint_1`` … ``joint_7``, ``gripper`` in that order, each ``{"id", "drive_mode", "homing_offset",
"range_min", "range_max"}`` as ints, 4-space indent, no final newline (robocal's :func:`~..lerobot.dumps_current`).
Its ``DamiaoMotorsBus`` never applies ``homing_offset``, ``drive_mode`` or the range: a joint angle is the motor's
reading in degrees, relative to the zero stored **in the motor** (``set_zero_position()``, 0xFE). So the file holds
no offset: as a joint map it says "every joint reads its angle directly" (offset 0, direction +1), and it is right
only when the motors hold the joints' zeros (``robocal sweep --auto --write-zero``). LeRobot writes −90…90 for every
joint; robocal writes the range measured between the stops (degrees, rounded inward to whole degrees), or the
URDF's limits when no measurement is at hand.

The writer refuses a calibration whose offsets are not zero (LeRobot would read those joints off by the offset),
naming the joints. The reader names the joints as the profile does (``joint_3`` → ``openarm_right_joint3``), or as
the URDF's OpenArm joints when no profile is given.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np

from ...core.jointmap import RobotCalibration
from ...core.lerobot import MotorCalibration
from ...core.profile import RobotProfile
from ...errors import FileFormatError, InvalidCalibrationError
from ...fileio import MAX_DOCUMENT_BYTES, atomic_write_text, read_text
from ..lerobot import dumps_current, parse_current
from ..urdf import UrdfModel
from ._base import CalibrationFile, Content, FormatSpec, Traits

__all__ = ["MOTORS", "SPEC", "openarm_names"]

MOTORS = ("joint_1", "joint_2", "joint_3", "joint_4", "joint_5", "joint_6", "joint_7", "gripper")
"""LeRobot's OpenArm motor names in bus order (``config_openarm_follower.py``); ids 1-8."""
ZERO_TOL_RAD = math.radians(0.05)
"""An offset this small is taken as the motor's own zero (the file can hold no other; LeRobot reads the joint off
by it): ``--write-zero`` stores each zero within 0.02° of the joint's 0."""


def openarm_names(profile: RobotProfile | None, urdf: UrdfModel | None) -> dict[str, str]:
    """LeRobot motor name → joint name: the profile's ``upstream_name`` map, else the URDF's OpenArm side, else as is."""
    if profile is not None:
        by_upstream = {j.upstream_name: j.name for j in profile.joints}
        if all(m in by_upstream for m in MOTORS):
            return {m: by_upstream[m] for m in MOTORS}
    if urdf is not None:
        for side in ("right", "left"):
            names = {m: (f"openarm_{side}_joint{m[-1]}" if m != "gripper" else f"openarm_{side}_gripper_motor")
                     for m in MOTORS}
            if all(n in urdf.joint_names for n in names.values()):
                return names
    return {m: m for m in MOTORS}


def read(
    path: Path, *, urdf: UrdfModel | None = None, profile: RobotProfile | None = None, **_: Any
) -> CalibrationFile:
    """Read an OpenArm LeRobot file as a joint map (offset 0, direction +1 for every motor)."""
    source = str(path)
    cals = parse_current(read_text(path, "calibration file", limit=MAX_DOCUMENT_BYTES), source)
    if tuple(cals) != MOTORS:
        raise FileFormatError(f"{source}: an OpenArm LeRobot file names the motors {', '.join(MOTORS)} in that order")
    for name, c in cals.items():
        if c.drive_mode != 0 or c.homing_offset != 0:
            raise FileFormatError(
                f"{source}: motor {name}: drive_mode {c.drive_mode}, homing_offset {c.homing_offset}; LeRobot's "
                "Damiao bus ignores both, an OpenArm file has 0 (the zero is in the motor)"
            )
    names = openarm_names(profile, urdf)
    joints = [names[m] for m in MOTORS]
    cal = RobotCalibration(joints, np.ones(len(joints)), np.zeros(len(joints)))
    ranges = {names[m]: (math.radians(c.range_min), math.radians(c.range_max)) for m, c in cals.items()}
    ids = {names[m]: c.id for m, c in cals.items()}
    return CalibrationFile(cal, ids, "openarm-lerobot", source, (), ranges)


def dumps(cf: CalibrationFile, urdf: UrdfModel | None, profile: RobotProfile | None) -> str:
    """The file's text (see the module docstring); ``cf`` must hold every OpenArm joint with offset 0."""
    names = openarm_names(profile, urdf)
    cal = cf.calibration
    lacking = [n for n in names.values() if n not in cal.joint_names]
    if lacking:
        raise InvalidCalibrationError(f"format openarm-lerobot needs every OpenArm joint; missing {', '.join(lacking)}")
    off = [
        f"{n} ({math.degrees(cal.homing_offset[cal.index(n)]):+.3f}°)"
        for n in names.values()
        if abs(cal.homing_offset[cal.index(n)]) > ZERO_TOL_RAD or cal.direction[cal.index(n)] != 1.0
    ]
    if off:
        raise InvalidCalibrationError(
            f"format openarm-lerobot holds no offsets (LeRobot reads each Damiao motor against its own zero); "
            f"joints {', '.join(off)} are not at the motor's zero or not direction +1: store the zeros in the "
            "motors first (robocal sweep --auto --write-zero)"
        )
    out: dict[str, MotorCalibration] = {}
    for i, m in enumerate(MOTORS, start=1):
        joint = names[m]
        lo, hi = _range(joint, cf.ranges_rad, urdf)
        out[m] = MotorCalibration(i, 0, 0, lo, hi)
    return dumps_current(out)


def _range(joint: str, ranges: Mapping[str, tuple[float, float]], urdf: UrdfModel | None) -> tuple[int, int]:
    if joint in ranges:
        lo, hi = ranges[joint]
    elif urdf is not None and joint in urdf.joint_names:
        lo, hi = urdf.limits(joint)
    else:
        return -90, 90  # LeRobot's own default, when nothing better is known
    # inward to whole degrees; a limit within 0.01° of a whole degree (a URDF's 6 decimals) is that degree
    return math.ceil(math.degrees(lo) - 0.01), math.floor(math.degrees(hi) + 0.01)


def write(
    path: Path, cf: CalibrationFile, urdf: UrdfModel | None, profile: RobotProfile | None = None, **_: Any
) -> None:
    """Write the file atomically (validated first)."""
    atomic_write_text(path, dumps(cf, urdf, profile))


def sniff(content: Content) -> bool:
    """A JSON object of exactly the OpenArm's eight LeRobot motors, each with ``range_min``."""
    data = content.data
    return (
        content.kind == "json"
        and isinstance(data, dict)
        and tuple(data) == MOTORS
        and all(isinstance(v, dict) and "range_min" in v for v in data.values())
    )


SPEC = FormatSpec(
    "openarm-lerobot", read, write, sniff, sniff_rank=1, suffixes=(), traits=Traits.IDS | Traits.SELF_CONTAINED
)
