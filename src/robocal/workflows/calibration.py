"""Convert calibration files between formats and check them against a URDF."""

from __future__ import annotations

import math
import os
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

from ..errors import UsageError
from ..formats import CalibrationFile, read_calibration, write_calibration
from ..formats.urdf import UrdfModel, read_urdf

__all__ = ["CheckReport", "JointCheck", "check_calibration", "convert_file"]


@dataclass(frozen=True)
class ConvertResult:
    """What :func:`convert_file` did."""

    src_format: str
    dst_format: str
    joints: tuple[str, ...]
    notes: tuple[str, ...]


def convert_file(
    src: str | os.PathLike[str],
    dst: str | os.PathLike[str],
    *,
    src_format: str | None = None,
    dst_format: str | None = None,
    urdf_path: str | os.PathLike[str] | None = None,
    joints: Sequence[str] | None = None,
) -> ConvertResult:
    """Convert one calibration file to another format.

    Directions, ids and joint order come from the URDF where the source format lacks them; ``joints`` selects
    and orders joints (and is the order of positional formats). Everything is validated before anything is
    written; the destination is written atomically with a ``.bak``.
    """
    urdf = read_urdf(urdf_path) if urdf_path is not None else None
    cf = read_calibration(src, src_format, urdf=urdf, joint_order=joints)
    cal = cf.calibration
    if joints is not None and tuple(joints) != cal.joint_names:
        cal = cal.select(joints)
    out = CalibrationFile(cal, {k: v for k, v in cf.ids.items() if k in cal.joint_names}, cf.fmt, cf.source)
    if Path(src).resolve() == Path(dst).resolve() and (dst_format or cf.fmt) == cf.fmt:
        raise UsageError(f"source and destination are the same file ({src}) in the same format")
    written = write_calibration(dst, out, dst_format, urdf=urdf, joint_order=joints)
    return ConvertResult(cf.fmt, written, cal.joint_names, cf.notes)


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
        extra: File joints the URDF does not have.
        joints: Per-joint results for the matched joints.
    """

    calibration_source: str
    urdf_source: str
    matched: tuple[str, ...]
    missing: tuple[str, ...]
    extra: tuple[str, ...]
    joints: tuple[JointCheck, ...]

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
            out.append(f"joints in the calibration file but not in the URDF: {', '.join(self.extra)}")
        for j in self.joints:
            out.extend(f"{j.name}: {w}" for w in j.warnings)
        return tuple(out)

    @property
    def ok(self) -> bool:
        """True when the file and the URDF agree completely."""
        return not self.warnings


def check_calibration(cf: CalibrationFile, urdf: UrdfModel) -> CheckReport:
    """Match a calibration file's joints against a URDF and compare ``id`` / ``direction``.

    Only ``homing_offset`` is authoritative in a Lite calibration file; ``id`` and ``direction`` are copies of
    the URDF's ``<ros2_control>`` params that the robot ignores, so any disagreement is a warning here.
    """
    expected = urdf.calibration_joint_names()
    cal = cf.calibration
    matched = tuple(n for n in expected if n in cal.joint_names)
    missing = tuple(n for n in expected if n not in cal.joint_names)
    extra = tuple(n for n in cal.joint_names if n not in expected)
    results = []
    for name in matched:
        warnings: list[str] = []
        jm = cal.joint_map(name)
        u_dir = urdf.direction(name)  # a malformed param is bad input (FileFormatError), not a warning
        u_id = urdf.motor_id(name)
        file_id = cf.ids.get(name)
        if u_dir is not None and u_dir != jm.direction:  # berkeley-offsets takes its directions from the URDF
            warnings.append(
                f"direction {jm.direction:+d} in the file disagrees with {u_dir:+d} in the URDF "
                "(the robot uses the URDF's)"
            )
        if u_id is not None and file_id is not None and u_id != file_id:
            warnings.append(
                f"id {file_id} in the file disagrees with can_id {u_id} in the URDF (the robot uses the URDF's)"
            )
        if jm.scale == 1.0 and abs(jm.homing_offset) > math.pi:
            warnings.append(
                f"|homing_offset| = {abs(jm.homing_offset):.3f} rad > pi: direction flipped or zero off by a turn?"
            )
        results.append(JointCheck(name, jm.homing_offset, jm.direction, file_id, tuple(warnings)))
    return CheckReport(cf.source, urdf.source, matched, missing, extra, tuple(results))
