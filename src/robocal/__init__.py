"""robocal: calibrate robots.

Joint zero offsets for Robstride, Feetech and Dynamixel joints, LeRobot calibration files and
normalisation, and Universal Robots kinematic calibration correction. The math lives in
:mod:`robocal.core` (pure numpy); hardware, files and the CLI are layered around it.
"""

from __future__ import annotations

from .errors import CalibError as CalibError

__all__ = ["CalibError", "__version__"]


def __getattr__(name: str) -> str:
    """``robocal.__version__``, looked up on first use (the lookup is slow; ``robocal`` starts without it)."""
    if name != "__version__":
        raise AttributeError(f"module 'robocal' has no attribute {name!r}")
    from importlib.metadata import PackageNotFoundError, version

    try:
        found = version("robocal")
    except PackageNotFoundError:  # running from a source tree without installation
        found = "0.0.0+src"
    globals()["__version__"] = found
    return found
