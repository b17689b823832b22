"""Calibration files in and out; validation happens here.

The package itself imports nothing: ``from robocal.formats import read_calibration`` loads
:mod:`.calibration` on first use, so a light module of this package can be imported without every format.
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from .calibration import FORMATS as FORMATS
    from .calibration import CalibrationFile as CalibrationFile
    from .calibration import detect_format as detect_format
    from .calibration import read_calibration as read_calibration
    from .calibration import write_calibration as write_calibration

__all__ = ["FORMATS", "CalibrationFile", "detect_format", "read_calibration", "write_calibration"]


def __getattr__(name: str) -> Any:
    """The names of :data:`__all__` from :mod:`.calibration`, imported on first use."""
    if name in __all__:
        return getattr(importlib.import_module(".calibration", __name__), name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
