"""``robocal``: robocal's canonical joint map YAML (direction, homing_offset, scale, optional id and range per joint).

``range: [lower, upper]`` is the travel measured between a joint's stops, in the joint frame (rad, or m for a
prismatic joint), where a sweep measured it; it is carried through ``robocal convert`` to the formats that store
a range (``openarm-lerobot``, ``openarm-ros2``). Files without it read as before.
"""

from __future__ import annotations

import json
from collections.abc import Mapping, Sequence
from pathlib import Path
from types import MappingProxyType
from typing import Any

from ...core.jointmap import RobotCalibration
from ...core.profile import RobotProfile
from ...errors import FileFormatError
from ...fileio import atomic_write_text
from .._numbers import parse_direction, parse_finite, parse_motor_id
from .._yaml import yaml_float
from ..urdf import UrdfModel
from ._base import CalibrationFile, Content, FormatSpec, Traits, check_unique_ids, ids_from, yaml_data

ROBOCAL_FORMAT_TAG = "robocal-joint-map"


def read(path: Path, parsed_yaml: Any = None, **_: Any) -> CalibrationFile:
    """Read a ``robocal`` joint map."""
    source = str(path)
    data = yaml_data(path, parsed_yaml)
    if not isinstance(data, Mapping) or data.get("format") != ROBOCAL_FORMAT_TAG:
        raise FileFormatError(f"{source}: not a robocal joint map (expected 'format: {ROBOCAL_FORMAT_TAG}')")
    version = data.get("version")
    if version != 1:
        raise FileFormatError(f"{source}: version {version!r} is not supported (expected 1)")
    joints = data.get("joints")
    if not isinstance(joints, Mapping) or not joints:
        raise FileFormatError(f"{source}: 'joints' must be a non-empty mapping")
    names, dirs, offs, scales = [], [], [], []
    ids: dict[str, int] = {}
    ranges: dict[str, tuple[float, float]] = {}
    for name, entry in joints.items():
        where = f"{source}: joint {name!r}"
        if not isinstance(entry, Mapping):
            raise FileFormatError(f"{where}: expected a mapping")
        allowed = {"id", "direction", "homing_offset", "scale", "raw_unit", "joint_unit", "range"}
        extra = [str(k) for k in entry if k not in allowed]
        if extra:
            raise FileFormatError(
                f"{where}: unknown key {', '.join(extra)}; expected {', '.join(sorted(allowed))}"
            )
        for key in ("direction", "homing_offset"):
            if key not in entry:
                raise FileFormatError(f"{where}: missing key {key}")
        if "id" in entry:
            ids[str(name)] = parse_motor_id(entry["id"], where)
        dirs.append(parse_direction(entry["direction"], where))
        offs.append(parse_finite(entry["homing_offset"], where, "homing_offset"))
        scale = parse_finite(entry.get("scale", 1.0), where, "scale")
        if scale <= 0:
            raise FileFormatError(f"{where}: scale {scale} must be > 0")
        scales.append(scale)
        names.append(str(name))
        if "range" in entry:
            ranges[str(name)] = _range(entry["range"], where)
    check_unique_ids(ids, source)
    return CalibrationFile(
        RobotCalibration(names, dirs, offs, scales), MappingProxyType(ids), "robocal", source, (), ranges
    )


def _range(value: Any, where: str) -> tuple[float, float]:
    """A ``range: [lower, upper]`` entry (finite, lower below upper)."""
    if not isinstance(value, Sequence) or isinstance(value, str) or len(value) != 2:
        raise FileFormatError(f"{where}: range must be a list [lower, upper]")
    lo = parse_finite(value[0], where, "range lower")
    hi = parse_finite(value[1], where, "range upper")
    if not lo < hi:
        raise FileFormatError(f"{where}: range lower {lo} is not below upper {hi}")
    return lo, hi


def write(
    path: Path, cf: CalibrationFile, urdf: UrdfModel | None, profile: RobotProfile | None = None, **_: Any
) -> None:
    """Write a ``robocal`` joint map (ids where the data, URDF or profile give them)."""
    cal = cf.calibration
    ids = ids_from(cal, cf.ids, urdf, profile)
    lines = [
        "# robocal joint map: q_joint = direction * scale * (raw - homing_offset)",
        "# homing_offset is in the motor's raw unit; scale converts raw units to joint units (rad or m).",
        *(["# range: the travel measured between the joint's stops, joint units."] if cf.ranges_rad else []),
        f"format: {ROBOCAL_FORMAT_TAG}",
        "version: 1",
        "joints:",
    ]
    for n, d, h, s in zip(cal.joint_names, cal.direction, cal.homing_offset, cal.scale, strict=True):
        lines.append(f"  {json.dumps(n)}:")
        if n in ids:
            lines.append(f"    id: {ids[n]}")
        lines.append(f"    direction: {int(d)}")
        lines.append(f"    homing_offset: {yaml_float(h)}")
        lines.append(f"    scale: {yaml_float(s)}")
        if n in cf.ranges_rad:
            lo, hi = cf.ranges_rad[n]
            lines.append(f"    range: [{yaml_float(lo)}, {yaml_float(hi)}]")
    atomic_write_text(path, "\n".join(lines) + "\n")


def sniff(content: Content) -> bool:
    """A YAML mapping tagged ``format: robocal-joint-map``."""
    return content.kind == "yaml" and content.data.get("format") == ROBOCAL_FORMAT_TAG


_TRAITS = Traits.DIRECTIONS | Traits.IDS | Traits.SELF_CONTAINED
SPEC = FormatSpec("robocal", read, write, sniff, sniff_rank=0, traits=_TRAITS)
