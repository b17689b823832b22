"""Options and value parsers the ``robocal kinematics`` commands share."""

from __future__ import annotations

import math
from pathlib import Path
from typing import Annotated

import typer

from ..errors import UsageError

__all__ = [
    "BaseLinkOption",
    "CameraInfoOption",
    "CameraOnToolOption",
    "KindOption",
    "TipLinkOption",
    "ToolXyzOption",
    "UrdfOption",
    "parse_numbers",
    "parse_xyz",
]

UrdfOption = Annotated[Path, typer.Option("--urdf", help="Expanded URDF of the arm.")]
BaseLinkOption = Annotated[str | None, typer.Option("--base-link", help="First link (default: URDF root).")]
TipLinkOption = Annotated[
    str | None, typer.Option("--tip-link", help="Link the tool is on (default: the leaf).")
]
KindOption = Annotated[str, typer.Option("--kind", help="points, touch, gauge or tag (camera images).")]
ToolXyzOption = Annotated[
    str, typer.Option("--tool-xyz", help="Nominal marker/ball/tip position in the tip link, metres: x,y,z.")
]
CameraInfoOption = Annotated[
    Path | None, typer.Option("--camera", help="--kind tag: camera intrinsics and image size (camera_info YAML).")
]
CameraOnToolOption = Annotated[
    bool, typer.Option("--camera-on-tool", help="--kind tag: the camera is on the tool, the target fixed.")
]


def _numbers(text: str) -> list[float]:
    """The numbers in ``text``, separated by commas or spaces (``ValueError`` on anything else)."""
    return [float(p) for p in text.replace(",", " ").split()]


def parse_numbers(text: str, flag: str, example: str) -> list[float]:
    """Finite numbers separated by commas or spaces (``flag`` and ``example`` name them in the error)."""
    try:
        values = _numbers(text)
    except ValueError:
        raise UsageError(f"{flag} {text!r}: expected numbers, e.g. {example}") from None
    if not values or not all(math.isfinite(v) for v in values):
        raise UsageError(f"{flag} {text!r}: expected finite numbers, e.g. {example}")
    return values


def parse_xyz(text: str, flag: str = "--tool-xyz") -> tuple[float, float, float]:
    """Three finite numbers in metres."""
    try:
        values = _numbers(text)
    except ValueError:
        raise UsageError(f"{flag} {text!r}: expected three numbers in metres, e.g. 0.012,0,-0.098") from None
    if len(values) != 3 or not all(math.isfinite(v) for v in values):
        raise UsageError(f"{flag} {text!r}: expected three finite numbers in metres")
    return values[0], values[1], values[2]
