"""``lerobot-legacy``: LeRobot's legacy array JSON (read only); its DEGREE joints convert exactly."""

from __future__ import annotations

from pathlib import Path
from types import MappingProxyType
from typing import Any

from ._base import CalibrationFile, Content, FormatSpec, Traits


def read(path: Path, **_: Any) -> CalibrationFile:
    """Read a legacy LeRobot file as a joint map; LINEAR motors are left out with a note."""
    from ...core.lerobot.legacy import degree_joint_map
    from ..lerobot import read_legacy  # lazy: only needed for this format

    cal = read_legacy(path)
    rc, linear = degree_joint_map(cal)  # DEGREE joints exactly; LINEAR ones are named and left out
    notes = (
        (f"{path}: LINEAR motor(s) {', '.join(linear)} left out (percent of a span, not a joint angle)",)
        if linear
        else ()
    )
    return CalibrationFile(rc, MappingProxyType({}), "lerobot-legacy", str(path), notes)


def sniff(content: Content) -> bool:
    """A JSON object with ``motor_names`` and ``homing_offset`` arrays."""
    return content.kind == "json" and "motor_names" in content.data and "homing_offset" in content.data


SPEC = FormatSpec("lerobot-legacy", read, None, sniff, sniff_rank=1, traits=Traits.DIRECTIONS)
