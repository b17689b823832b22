"""``berkeley-offsets``: Berkeley-Humanoid-Lite-Lowlevel ``{"position_offsets": [...]}``.

The offsets are in the joint frame (``q = direction * raw - offset``) and positional: the robot's low-level code
reads them by index in its own joint order, which robocal writes as a ``# joint order:`` comment.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from pathlib import Path
from types import MappingProxyType
from typing import Any

import numpy as np

from ...core.conventions import berkeley_offset_from_homing, homing_from_berkeley_offset
from ...core.jointmap import RobotCalibration
from ...core.profile import RobotProfile
from ...errors import FileFormatError, JointMismatchError, UsageError
from ...fileio import MAX_DOCUMENT_BYTES, atomic_write_text, read_text
from .._numbers import format_float, parse_finite
from .._yaml import load_yaml
from ..profiles import builtin_profile_names, joint_direction, joint_motor_id, profile_for_joints
from ..urdf import UrdfModel
from ._base import CalibrationFile, Content, FormatSpec, require_rad

BERKELEY_ORDER_COMMENT = "# joint order: "


def _no_order_message(what: str) -> str:
    return (
        f"{what}: berkeley-offsets is positional (its reader takes the offsets by index, in the order of the "
        "robot's low-level code, which is not the URDF's document order); pass --joints a,b,... for the order, "
        f"or --robot NAME for a robot robocal knows ({', '.join(builtin_profile_names())}) or a profile file"
    )


def _order_from_comment(text: str) -> list[str] | None:
    """The ``# joint order: a, b, ...`` line robocal writes at the top of a berkeley-offsets file, if any."""
    for line in text.splitlines():
        if line.startswith(BERKELEY_ORDER_COMMENT):
            names = [n.strip() for n in line[len(BERKELEY_ORDER_COMMENT) :].split(",")]
            return names if all(names) else None
        if line.strip() and not line.lstrip().startswith("#"):
            return None
    return None


def _berkeley_order(
    joint_order: Sequence[str] | None, profile: RobotProfile | None, what: str
) -> list[str] | None:
    if joint_order is not None:
        names = list(joint_order)
        if profile is not None:  # upstream names (left_hip_roll_joint) are accepted for the URDF names
            names = [profile.joint(n).name if n in profile.upstream_names else n for n in names]
        return names
    if profile is not None:
        return list(profile.joint_names)
    return None


def _berkeley_directions(
    order: Sequence[str], urdf: UrdfModel | None, profile: RobotProfile | None, source: str
) -> list[int]:
    """Directions by precedence: the URDF's ``direction`` param, else the profile's."""
    dirs = []
    lacking = []
    for name in order:
        if urdf is not None and not urdf.has_joint(name) and name not in urdf.joint_params:
            raise JointMismatchError(f"{source}: joint {name!r} is not in URDF {urdf.source}")
        d = joint_direction(name, urdf, profile)  # the file stores none
        if d is None:
            lacking.append(name)
            continue
        dirs.append(d)
    if lacking:
        have = []
        if urdf is not None:
            have.append(f"URDF {urdf.source} has no <param name='direction'>")
        have.append(f"profile {profile.name} has none" if profile is not None else "no robot profile")
        raise UsageError(
            f"{source}: berkeley-offsets holds joint-frame offsets and needs each joint's direction; none for "
            f"{', '.join(lacking)} ({'; '.join(have)}); pass --robot NAME or a URDF with direction params"
        )
    return dirs


def read(
    path: Path,
    urdf: UrdfModel | None = None,
    joint_order: Sequence[str] | None = None,
    profile: RobotProfile | None = None,
    parsed_yaml: Any = None,
    **_: Any,
) -> CalibrationFile:
    """Read a ``berkeley-offsets`` file: the joint order from ``joint_order``, the file's comment or the profile."""
    source = str(path)
    text = read_text(path, "calibration file", limit=MAX_DOCUMENT_BYTES)  # also read for the joint-order comment
    data = parsed_yaml if parsed_yaml is not None else load_yaml(text, source)
    if not isinstance(data, Mapping) or "position_offsets" not in data:
        raise FileFormatError(f"{source}: expected a mapping with key position_offsets")
    extra = [str(k) for k in data if k != "position_offsets"]
    if extra:
        raise FileFormatError(f"{source}: unknown key {', '.join(extra)}; expected only position_offsets")
    raw = data["position_offsets"]
    if not isinstance(raw, Sequence) or isinstance(raw, str) or not raw:
        raise FileFormatError(f"{source}: position_offsets must be a non-empty list of numbers")
    offsets = [parse_finite(v, source, f"position_offsets[{i}]") for i, v in enumerate(raw)]
    written = _order_from_comment(text)
    if written is not None and len(written) != len(offsets):
        written = None  # a stale comment (the list was edited): not the file's order
    # --joints first, then the order the file names (robocal's own files), then the profile's
    order = (
        _berkeley_order(joint_order, profile, source) if joint_order is not None or written is None else None
    )
    notes: tuple[str, ...] = ()
    if order is None and written is None:
        raise UsageError(_no_order_message(source))
    if order is None and written is not None:
        order = written  # a file robocal wrote names its order; that is how its offsets are laid out
        if profile is None:
            profile = profile_for_joints(order)  # a known robot's joints give the directions
        elif list(profile.joint_names) != order and set(profile.joint_names) == set(order):
            notes = (
                f"{source}: its joints are in another order than robot {profile.name}'s low-level code reads "
                f"them ({', '.join(profile.joint_names)}); that code reads by index and would put offsets on "
                "other joints: rewrite it with --to berkeley-offsets (without --joints)",
            )
    elif written is not None and order is not None and written != order:
        raise JointMismatchError(
            f"{source}: the file says its joint order is {', '.join(written)}, but --joints gives "
            f"{', '.join(order)}; the offsets would land on other joints"
        )
    assert order is not None
    if len(order) != len(offsets):
        raise JointMismatchError(
            f"{source}: {len(offsets)} offsets but {len(order)} joints in the order ({', '.join(order)})"
        )
    dirs = _berkeley_directions(order, urdf, profile, source)
    h = homing_from_berkeley_offset(np.array(dirs, float), np.array(offsets))
    ids: dict[str, int] = {}
    for n in order:
        mid = joint_motor_id(n, urdf, profile)
        if mid is not None:
            ids[n] = int(mid)
    return CalibrationFile(
        RobotCalibration(order, dirs, h, 1.0), MappingProxyType(ids), "berkeley-offsets", source, notes
    )


def write(
    path: Path,
    cf: CalibrationFile,
    urdf: UrdfModel | None,
    joint_order: Sequence[str] | None = None,
    profile: RobotProfile | None = None,
    **_: Any,
) -> None:
    """Write a ``berkeley-offsets`` file in the order of ``joint_order`` or the robot's low-level code."""
    cal = cf.calibration
    if profile is None and joint_order is None:  # a calibration of exactly a known robot's joints
        profile = profile_for_joints(cal.joint_names)
    order = _berkeley_order(joint_order, profile, "berkeley-offsets")
    if order is None:
        raise UsageError(_no_order_message(f"cannot write {path}"))
    in_order = set(order)
    missing = [n for n in order if n not in cal]
    extra = [n for n in cal.joint_names if n not in in_order]
    if missing or extra:
        by = "--joints" if joint_order is not None else f"robot {profile.name}"  # type: ignore[union-attr]
        detail = "; ".join(
            f"{what}: {', '.join(names)}"
            for what, names in (("not in the calibration", missing), (f"not in {by}", extra))
            if names
        )
        raise JointMismatchError(
            f"berkeley-offsets is positional in the order of {by}, but the joints differ ({detail}); "
            "pass --joints for the order"
        )
    cal = cal.select(order)
    require_rad(cal, "berkeley-offsets")
    offs = berkeley_offset_from_homing(cal.direction, cal.homing_offset)
    body = ", ".join(format_float(v) for v in offs)
    robot = f" (robot {profile.name})" if profile is not None and joint_order is None else ""
    text = (
        "# Berkeley-Humanoid-Lite-Lowlevel joint offsets (rad, joint frame): q = direction*raw - offset\n"
        f"{BERKELEY_ORDER_COMMENT}{', '.join(cal.joint_names)}\n"
        f"# read by index in this order{robot}\n"
        f"position_offsets: [{body}]\n"
    )
    atomic_write_text(path, text)


def sniff(content: Content) -> bool:
    """A JSON or YAML mapping with a ``position_offsets`` key."""
    return content.kind != "xml" and "position_offsets" in content.data


SPEC = FormatSpec("berkeley-offsets", read, write, sniff, sniff_rank=1)
