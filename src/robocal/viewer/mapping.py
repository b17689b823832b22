"""Raw source values → joint positions for the viewer's joints, through a calibration (pure numpy)."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import numpy.typing as npt

from ..core.arrays import FloatArray
from ..core.jointmap import RobotCalibration

__all__ = ["JointMapper"]



class JointMapper:
    """Maps raw values of ``joint_names`` to joint positions; joints the calibration lacks pass through.

    Args:
        joint_names: The viewer's joints (the array axis).
        calibration: The map (raw units → rad); None maps every joint as is.
        label: Shown on the page (e.g. the file name, ``identity``).
    """

    def __init__(
        self, joint_names: Sequence[str], calibration: RobotCalibration | None, label: str = ""
    ) -> None:
        self.joint_names = tuple(joint_names)
        self.label = label
        known = [n for n in self.joint_names if calibration is not None and n in calibration]
        self.covered = tuple(known)
        self.missing = tuple(n for n in self.joint_names if n not in known)
        self._sel = np.array([self.joint_names.index(n) for n in known], dtype=np.intp)
        self._cal = calibration.select(known) if calibration is not None and known else None

    def to_joint(self, raw: npt.ArrayLike) -> FloatArray:
        """Raw ``(N,)`` → joint positions ``(N,)`` (NaN stays NaN)."""
        r = np.array(raw, dtype=np.float64)
        if self._cal is not None:
            r[self._sel] = self._cal.to_joint(r[self._sel])
        return r
