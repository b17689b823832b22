"""The calibrated joints of a Robstride robot: URDF + robot profile + calibration file → ``JointSpec`` list.

Used by the sweep, the power-on check and the runtime robot.
"""

from __future__ import annotations

import os
from collections.abc import Sequence
from pathlib import Path

from ...backends.sources import JointSpec
from ...core.jointmap import RobotCalibration
from ...core.profile import RobotProfile
from ...errors import FileFormatError
from ...formats import CalibrationFile, read_calibration
from ...formats.profiles import joint_direction, joint_motor_id, resolve_profile
from ...formats.urdf import UrdfModel, read_urdf

__all__ = ["joint_calibration", "joints_from_urdf", "read_joints"]


def joints_from_urdf(
    urdf: UrdfModel,
    profile: RobotProfile | None = None,
    calibration: CalibrationFile | None = None,
) -> list[JointSpec]:
    """The calibrated joints with direction, limits, CAN id and model.

    The joints are the URDF's ``<ros2_control>`` joints when it has any, else the profile's (in the profile's
    order), else the URDF's movable joints. A direction comes from the URDF's ``direction`` param, else the
    calibration file (formats that store one), else the profile; CAN id and model from the URDF's params, else
    the profile. Limits always come from the URDF.

    Raises:
        FileFormatError: A joint has no direction in any source, or no limits.
    """
    if urdf.ros2_control_joint_names or profile is None:
        names = list(urdf.calibration_joint_names())
    else:
        names = list(profile.joint_names)
    file_dirs: dict[str, int] = {}
    if calibration is not None and calibration.fmt != "berkeley-offsets":
        cal = calibration.calibration
        file_dirs = {n: int(d) for n, d in zip(cal.joint_names, cal.direction, strict=True)}
    out = []
    lacking = []
    for name in names:
        d = joint_direction(name, urdf, profile, file_dirs)
        if d is None:
            lacking.append(name)
            continue
        lo, up = urdf.limits(name)
        can_id = joint_motor_id(name, urdf, profile)
        model = urdf.param(name, "model") or (
            profile.joint(name).model if profile and name in profile else None
        )
        out.append(JointSpec(name, can_id or 0, model or "rs-00", d, lo, up))
    if lacking:
        where = "no robot profile" if profile is None else f"profile {profile.name} has none"
        raise FileFormatError(
            f"URDF {urdf.source}: no direction for {', '.join(lacking)}: no <param name='direction'>, "
            f"none in a calibration file, {where}; pass --robot NAME or a profile file (docs/profiles.md)"
        )
    if not out:
        raise FileFormatError(f"URDF {urdf.source}: no joints to calibrate")
    owner: dict[int, str] = {}
    for j in out:
        if j.can_id > 0 and owner.setdefault(j.can_id, j.name) != j.name:
            raise FileFormatError(
                f"URDF {urdf.source}: joints {owner[j.can_id]!r} and {j.name!r} share CAN id {j.can_id}"
            )
    return out


def read_joints(
    urdf_path: str | Path,
    calibration_path: str | Path,
    robot: str | os.PathLike[str] | RobotProfile | None = None,
) -> tuple[list[JointSpec], CalibrationFile]:
    """Read a URDF and a calibration file (any format robocal reads): the robot's joints and the file.

    Args:
        urdf_path: The URDF.
        calibration_path: The calibration file.
        robot: Robot profile (default: the built-in robot the URDF's joint names match).

    Returns:
        The joints of :func:`joints_from_urdf` (URDF order) and the calibration file as read.
    """
    urdf = read_urdf(urdf_path)
    profile = resolve_profile(robot, urdf)
    cf = read_calibration(calibration_path, urdf=urdf, robot=profile)
    return joints_from_urdf(urdf, profile, cf), cf


def joint_calibration(cf: CalibrationFile, joints: Sequence[JointSpec]) -> RobotCalibration:
    """The file's calibration of ``joints``, in their order, with their directions (the URDF's or profile's)."""
    return cf.calibration.select([j.name for j in joints]).with_directions(
        {j.name: j.direction for j in joints}
    )
