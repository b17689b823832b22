"""The calibrated joints of a Robstride robot: URDF + robot profile + calibration file → ``JointSpec`` list.

Used by the sweep, the power-on check and the runtime robot.
"""

from __future__ import annotations

from ..backends.sources import JointSpec
from ..core.profile import RobotProfile
from ..errors import FileFormatError
from ..formats import CalibrationFile
from ..formats.urdf import UrdfModel

__all__ = ["joints_from_urdf"]


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
        d = urdf.direction(name)
        if d is None:
            d = file_dirs.get(name)
        if d is None and profile is not None:
            d = profile.direction(name)
        if d is None:
            lacking.append(name)
            continue
        lo, up = urdf.limits(name)
        can_id = urdf.motor_id(name)
        if can_id is None and profile is not None:
            can_id = profile.motor_id(name)
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
