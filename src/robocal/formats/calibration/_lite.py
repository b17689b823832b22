"""The Lite schema ``{joint: {id, direction, homing_offset}}`` that ``lite-json`` and ``lite-yaml`` share."""

from __future__ import annotations

from collections.abc import Mapping
from types import MappingProxyType
from typing import Any

from ...core.jointmap import RobotCalibration
from ...core.profile import RobotProfile
from ...errors import FileFormatError, UsageError
from .._numbers import parse_direction, parse_finite, parse_motor_id
from ..urdf import UrdfModel
from ._base import CalibrationFile, check_unique_ids, ids_from, require_rad

LITE_KEYS = ("id", "direction", "homing_offset")


def parse_lite(data: Any, source: str, fmt: str) -> CalibrationFile:
    """Validate a parsed Lite document and return its calibration (scale 1, rad)."""
    if not isinstance(data, Mapping) or not data:
        raise FileFormatError(
            f"{source}: expected a mapping of joint name -> {{id, direction, homing_offset}}"
        )
    names: list[str] = []
    dirs: list[int] = []
    offs: list[float] = []
    ids: dict[str, int] = {}
    for name, entry in data.items():
        if not isinstance(name, str) or not name:
            raise FileFormatError(f"{source}: joint name {name!r} is not a string")
        where = f"{source}: joint {name!r}"
        if not isinstance(entry, Mapping):
            raise FileFormatError(f"{where}: expected a mapping with keys id, direction, homing_offset")
        missing = [k for k in ("direction", "homing_offset") if k not in entry]
        if missing:
            raise FileFormatError(f"{where}: missing key {', '.join(missing)}")
        extra = [str(k) for k in entry if k not in LITE_KEYS]
        if extra:
            raise FileFormatError(
                f"{where}: unknown key {', '.join(extra)}; expected id, direction, homing_offset"
            )
        if "id" in entry:
            ids[name] = parse_motor_id(entry["id"], where)
        dirs.append(parse_direction(entry["direction"], where))
        offs.append(parse_finite(entry["homing_offset"], where, "homing_offset"))
        names.append(name)
    check_unique_ids(ids, source)
    return CalibrationFile(RobotCalibration(names, dirs, offs, 1.0), MappingProxyType(ids), fmt, source)


def lite_entries(
    cf: CalibrationFile, urdf: UrdfModel | None, fmt: str, profile: RobotProfile | None = None
) -> dict[str, dict[str, Any]]:
    """The entries to write: every joint needs a motor id (from the data, the URDF or the profile)."""
    cal = cf.calibration
    require_rad(cal, fmt)
    ids = ids_from(cal, cf.ids, urdf, profile)
    missing = [n for n in cal.joint_names if n not in ids]
    if missing:
        if urdf is None and profile is None:
            hint = "pass --urdf with id/can_id params, or --robot NAME"
        elif urdf is None:
            hint = f"profile {profile.name} has none for them; pass --urdf with id/can_id params"  # type: ignore[union-attr]
        else:
            where = f"URDF {urdf.source} has no id/can_id param for them"
            where += f" and profile {profile.name} none either" if profile is not None else ""
            hint = f"{where}; pass --robot NAME or a profile file (docs/profiles.md)"
        raise UsageError(
            f"format {fmt} needs a motor id for every joint; missing for {', '.join(missing)} ({hint})"
        )
    check_unique_ids(ids, f"calibration for {fmt}")
    return {
        n: {"id": ids[n], "direction": int(d), "homing_offset": float(h)}
        for n, d, h in zip(cal.joint_names, cal.direction, cal.homing_offset, strict=True)
    }
