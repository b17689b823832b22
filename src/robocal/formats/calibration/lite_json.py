"""``lite-json``: Lite-Lowlevel-Python ``calibration.json``, ``{joint: {id, direction, homing_offset}}``."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

from ...core.profile import RobotProfile
from ...errors import FileFormatError
from ...fileio import MAX_DOCUMENT_BYTES, atomic_write_text, read_text
from .._json import load_json
from ..urdf import UrdfModel
from ._base import CalibrationFile, Content, FormatSpec, Traits, first_value
from ._lite import lite_entries, parse_lite

_MOTOR_CONFIG_KEYS = ("position_controller", "current_controller", "powerstage")


def refuse_motor_configuration(data: object, source: str) -> None:
    """A Lite ``robot_configuration.json`` (per-joint controller settings, ``Infinity`` limits) is no calibration."""
    first = next(iter(data.values()), None) if isinstance(data, dict) else None
    if isinstance(first, dict) and any(k in first for k in _MOTOR_CONFIG_KEYS):
        raise FileFormatError(
            f"{source}: this is a motor configuration (per-joint {', '.join(k for k in _MOTOR_CONFIG_KEYS if k in first)}"
            " settings, like the Berkeley Humanoid Lite's robot_configuration.json), not a calibration"
        )


def read(path: Path, **_: Any) -> CalibrationFile:
    """Read a ``lite-json`` file."""
    text = read_text(path, "calibration file", limit=MAX_DOCUMENT_BYTES)
    try:  # before its Infinity values fail the strict JSON reader
        loose = json.loads(text)
    except (ValueError, RecursionError):
        loose = None
    refuse_motor_configuration(loose, str(path))
    return parse_lite(load_json(text, str(path), item="joint"), str(path), "lite-json")


def write(
    path: Path, cf: CalibrationFile, urdf: UrdfModel | None, profile: RobotProfile | None = None, **_: Any
) -> None:
    """Write a ``lite-json`` file (every joint needs a motor id)."""
    entries = lite_entries(cf, urdf, "lite-json", profile)
    for e in entries.values():
        if e["homing_offset"] == 0.0:
            e["homing_offset"] = 0.0  # normalise -0.0
    atomic_write_text(path, json.dumps(entries, indent=4) + "\n")


def sniff(content: Content) -> bool:
    """A JSON object of joint objects; a Lite motor configuration is refused, a LeRobot file is not this."""
    if content.kind != "json":
        return False
    refuse_motor_configuration(content.data, content.source)
    first = first_value(content.data)
    return isinstance(first, dict) and "range_min" not in first


_TRAITS = Traits.DIRECTIONS | Traits.IDS | Traits.SELF_CONTAINED
SPEC = FormatSpec("lite-json", read, write, sniff, sniff_rank=2, suffixes=(".json",), traits=_TRAITS)
