"""robocal: calibrate robots.

Joint zero offsets for Robstride, Feetech and Dynamixel joints, LeRobot calibration files and
normalisation, and Universal Robots kinematic calibration correction. The math lives in
:mod:`robocal.core` (pure numpy); hardware, files and the CLI are layered around it.
"""

from __future__ import annotations

from importlib.metadata import PackageNotFoundError, version

from .errors import CalibError as CalibError

try:
    __version__ = version("robocal")
except PackageNotFoundError:  # running from a source tree without installation
    __version__ = "0.0.0+src"

__all__ = ["CalibError", "__version__"]
