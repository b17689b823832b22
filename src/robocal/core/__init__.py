"""Pure numpy calibration math: import this from a control loop.

Nothing here does I/O, prints, or imports hardware or CLI dependencies.
"""

from __future__ import annotations

from .jointmap import JointMap as JointMap
from .jointmap import RobotCalibration as RobotCalibration

__all__ = ["JointMap", "RobotCalibration"]
