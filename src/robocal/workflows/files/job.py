"""Convert calibration files between formats and check them against a URDF."""

from __future__ import annotations

import math
import os
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

from ...core.profile import RobotProfile
from ...errors import UsageError
from ...formats import FORMATS, CalibrationFile, read_calibration, write_calibration
from ...formats.profiles import builtin_profile_names, resolve_profile
from ...formats.urdf import UrdfModel, read_urdf

__all__ = [
    "CheckReport",
    "FileCheck",
    "JointCheck",
    "check_calibration",
    "check_file",
    "convert_file",
    "format_names",
    "robot_profile_names",
]


def format_names() -> tuple[str, ...]:
    """The calibration formats robocal reads and writes, in the registry's order."""
    return tuple(FORMATS)


def robot_profile_names() -> tuple[str, ...]:
    """The robot profiles shipped with robocal, sorted."""
    return builtin_profile_names()


@dataclass(frozen=True)
class ConvertResult:
    """What :func:`convert_file` did."""

    src_format: str
    dst_format: str
    joints: tuple[str, ...]
    notes: tuple[str, ...]
    robot: str | None = None


def convert_file(
    src: str | os.PathLike[str],
    dst: str | os.PathLike[str],
    *,
    src_format: str | None = None,
    dst_format: str | None = None,
    urdf_path: str | os.PathLike[str] | None = None,
    joints: Sequence[str] | None = None,
    robot: str | os.PathLike[str] | RobotProfile | None = None,
) -> ConvertResult:
    """Convert one calibration file to another format.

    Directions and ids come from the URDF's params where the source format lacks them, else from the robot
    profile (``robot``, or the built-in one the URDF's joint names match). The order of positional formats
    (``berkeley-offsets``) is ``joints``, else the profile's, never the URDF's document order; ``joints`` also
    selects joints (URDF names, or a profile's upstream names). Everything is validated before anything is
    written; the destination is written atomically with a ``.bak``.
    """
    urdf = read_urdf(urdf_path) if urdf_path is not None else None
    profile = resolve_profile(robot, urdf)
    if joints is not None and profile is not None:
        joints = [profile.joint(n).name if n in profile.upstream_names else n for n in joints]
    cf = read_calibration(src, src_format, urdf=urdf, joint_order=joints, robot=profile)
    cal = cf.calibration
    if joints is not None and tuple(joints) != cal.joint_names:
        cal = cal.select(joints)
    ranges = {k: v for k, v in cf.ranges_rad.items() if k in cal}  # measured ranges go on to formats that keep them
    out = CalibrationFile(cal, {k: v for k, v in cf.ids.items() if k in cal}, cf.fmt, cf.source, (), ranges)
    if Path(src).resolve() == Path(dst).resolve() and (dst_format or cf.fmt) == cf.fmt:
        raise UsageError(f"source and destination are the same file ({src}) in the same format")
    written = write_calibration(dst, out, dst_format, urdf=urdf, joint_order=joints, robot=profile)
    return ConvertResult(cf.fmt, written, cal.joint_names, cf.notes, profile.name if profile else None)


@dataclass(frozen=True)
class JointCheck:
    """Result of checking one joint of a calibration file against the URDF."""

    name: str
    homing_offset: float | None
    direction: int | None
    motor_id: int | None
    warnings: tuple[str, ...]


@dataclass(frozen=True)
class CheckReport:
    """Result of :func:`check_calibration`.

    Attributes:
        matched: Joints present in both the file and the URDF (URDF order).
        missing: URDF calibration joints the file lacks.
        extra: File joints the URDF does not have (or, with a robot profile, joints the robot's code does not
            drive).
        joints: Per-joint results for the matched joints.
    """

    calibration_source: str
    urdf_source: str
    matched: tuple[str, ...]
    missing: tuple[str, ...]
    extra: tuple[str, ...]
    joints: tuple[JointCheck, ...]
    robot: str | None = None
    expected_from_profile: bool = False

    @property
    def n_expected(self) -> int:
        """Number of joints the URDF expects a calibration for."""
        return len(self.matched) + len(self.missing)

    @property
    def warnings(self) -> tuple[str, ...]:
        """Every warning, each naming its joint."""
        out: list[str] = []
        if self.missing:
            out.append(f"joints missing from the calibration file: {', '.join(self.missing)}")
        if self.extra:
            out.append(self.extra_message)
        for j in self.joints:
            out.extend(f"{j.name}: {w}" for w in j.warnings)
        return tuple(out)

    @property
    def extra_message(self) -> str:
        """The warning about :attr:`extra` joints."""
        if self.robot is not None and self.expected_from_profile:
            return (
                f"joints in the calibration file that robot {self.robot}'s code does not drive (or the URDF "
                f"lacks): {', '.join(self.extra)}"
            )
        return f"joints in the calibration file but not in the URDF: {', '.join(self.extra)}"

    @property
    def ok(self) -> bool:
        """True when the file and the URDF agree completely."""
        return not self.warnings


def check_calibration(
    cf: CalibrationFile, urdf: UrdfModel, profile: RobotProfile | None = None
) -> CheckReport:
    """Match a calibration file's joints against a URDF (and robot profile) and compare ``id`` / ``direction``.

    The joints expected are the URDF's ``<ros2_control>`` joints when it has any (the runtime drives those),
    else the profile's (what the robot's own low-level code drives), else the URDF's movable joints. Directions
    and ids can come from three places: the URDF's params, the calibration file (formats that store them) and
    the profile. Every pair that disagrees is a warning naming the joint and both sources.
    """
    if urdf.ros2_control_joint_names or profile is None:
        expected = urdf.calibration_joint_names()
    else:
        expected = profile.joint_names
    cal = cf.calibration
    expected_set = set(expected)
    matched = tuple(n for n in expected if n in cal)
    missing = tuple(n for n in expected if n not in cal)
    extra = tuple(n for n in cal.joint_names if n not in expected_set)
    spec = FORMATS.get(cf.fmt)  # berkeley-offsets takes directions from the URDF or the profile
    file_dirs = spec is not None and spec.stores_directions
    file_ids = spec is not None and spec.stores_ids
    pname = f"profile {profile.name}" if profile is not None else ""
    results = []
    for name in matched:
        warnings: list[str] = []
        jm = cal.joint_map(name)
        u_dir = urdf.direction(name)  # a malformed param is bad input (FileFormatError), not a warning
        u_id = urdf.motor_id(name)
        p_dir = profile.direction(name) if profile is not None else None
        p_id = profile.motor_id(name) if profile is not None else None
        f_dir = jm.direction if file_dirs else None
        file_id = cf.ids.get(name) if file_ids else None
        if u_dir is not None and f_dir is not None and u_dir != f_dir:
            warnings.append(
                f"direction {f_dir:+d} in the file disagrees with {u_dir:+d} in the URDF "
                "(the robot uses the URDF's)"
            )
        if p_dir is not None and f_dir is not None and p_dir != f_dir:
            warnings.append(f"direction {f_dir:+d} in the file disagrees with {p_dir:+d} in {pname}")
        if u_dir is not None and p_dir is not None and u_dir != p_dir:
            warnings.append(f"direction {u_dir:+d} in the URDF disagrees with {p_dir:+d} in {pname}")
        if u_id is not None and file_id is not None and u_id != file_id:
            warnings.append(
                f"id {file_id} in the file disagrees with can_id {u_id} in the URDF (the robot uses the URDF's)"
            )
        if p_id is not None and file_id is not None and p_id != file_id:
            warnings.append(f"id {file_id} in the file disagrees with id {p_id} in {pname}")
        if u_id is not None and p_id is not None and u_id != p_id:
            warnings.append(f"can_id {u_id} in the URDF disagrees with id {p_id} in {pname}")
        if jm.scale == 1.0 and abs(jm.homing_offset) > math.pi:
            warnings.append(
                f"|homing_offset| = {abs(jm.homing_offset):.3f} rad > pi: direction flipped or zero off by a turn?"
            )
        shown_id = cf.ids.get(name)
        if shown_id is None:
            shown_id = u_id if u_id is not None else p_id
        results.append(JointCheck(name, jm.homing_offset, jm.direction, shown_id, tuple(warnings)))
    return CheckReport(
        cf.source,
        urdf.source,
        matched,
        missing,
        extra,
        tuple(results),
        profile.name if profile else None,
        not urdf.ros2_control_joint_names and profile is not None,
    )


@dataclass(frozen=True)
class FileCheck:
    """What :func:`check_file` read and found.

    Attributes:
        report: The joint-by-joint comparison with the URDF (and profile).
        fmt: The calibration file's format (detected or given).
        notes: What reading the file noticed (each a warning).
        profile: The robot profile in effect (``robot`` or the one the URDF's joint names match), if any.
    """

    report: CheckReport
    fmt: str
    notes: tuple[str, ...]
    profile: RobotProfile | None


def check_file(
    calibration_path: str | os.PathLike[str],
    urdf_path: str | os.PathLike[str],
    fmt: str | None = None,
    robot: str | os.PathLike[str] | RobotProfile | None = None,
) -> FileCheck:
    """Read a calibration file and a URDF and check one against the other (:func:`check_calibration`).

    The URDF is read first, then the profile resolved (``robot``, else the built-in one the URDF matches), then
    the calibration file (format ``fmt``, detected when ``None``).
    """
    model = read_urdf(urdf_path)
    profile = resolve_profile(robot, model)
    cf = read_calibration(calibration_path, fmt, urdf=model, robot=profile)
    return FileCheck(check_calibration(cf, model, profile), cf.fmt, cf.notes, profile)
