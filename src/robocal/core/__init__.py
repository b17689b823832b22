"""Pure numpy calibration math: import this from a control loop.

Nothing here does I/O, prints, or imports hardware or CLI dependencies. The package itself imports nothing:
``from robocal.core import JointMap`` loads :mod:`.jointmap` (and numpy) on first use, so a light module such as
:mod:`.sweep_result` can be imported without numpy (the command line's help needs its defaults, not the math).
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from .jointmap import JointMap as JointMap
    from .jointmap import RobotCalibration as RobotCalibration

__all__ = ["JointMap", "RobotCalibration"]


def __getattr__(name: str) -> Any:
    """``JointMap`` and ``RobotCalibration`` from :mod:`.jointmap`, imported on first use."""
    if name in __all__:
        return getattr(importlib.import_module(".jointmap", __name__), name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
