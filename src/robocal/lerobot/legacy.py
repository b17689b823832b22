"""LeRobot legacy calibration (2024 → 2025-06): files, ``apply_calibration`` / ``revert_calibration``.

``cal`` is a :class:`~robocal.core.lerobot.LegacyCalibration` (the six arrays of the legacy JSON).
"""

from __future__ import annotations

import os
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt

from ..core.lerobot.legacy import (
    LegacyCalibration,
    apply_legacy,
    autocorrect_legacy,
    degree_joint_map,
    degrees_to_steps,
    legacy_calibration_from_poses,
    revert_legacy,
    to_robot_calibration,
)
from ..errors import InvalidCalibrationError
from ..formats import lerobot as _fmt

__all__ = [
    "LegacyCalibration",
    "apply_calibration",
    "autocorrect_calibration",
    "calibration_from_poses",
    "convert_degrees_to_steps",
    "degree_joint_map",
    "read_legacy",
    "revert_calibration",
    "to_robot_calibration",
    "write_legacy",
]

calibration_from_poses = legacy_calibration_from_poses
autocorrect_calibration = autocorrect_legacy
convert_degrees_to_steps = degrees_to_steps


def read_legacy(path: str | os.PathLike[str]) -> LegacyCalibration:
    """Read a legacy LeRobot calibration JSON (raises ``FileFormatError`` naming the file and key)."""
    return _fmt.read_legacy(path)


def write_legacy(path: str | os.PathLike[str], cal: LegacyCalibration) -> Path:
    """Write a legacy calibration byte-identical to LeRobot's ``json.dump`` (atomic, keeps ``NAME.bak``)."""
    return _fmt.write_legacy(path, cal)


def _one_motor(
    kernel: Callable[[npt.ArrayLike, LegacyCalibration], npt.NDArray[Any]],
    x: npt.ArrayLike,
    cal: LegacyCalibration,
) -> npt.NDArray[Any]:
    """A scalar for a one-motor calibration is that motor's value (result of shape ``()``)."""
    if not isinstance(cal, LegacyCalibration):
        raise InvalidCalibrationError(
            f"cal is a {type(cal).__name__}; expected a LegacyCalibration (see read_legacy)"
        )
    if len(cal.motor_names) == 1 and np.ndim(x) == 0:
        one: npt.NDArray[Any] = kernel(np.asarray(x)[np.newaxis], cal)[..., 0]
        return one
    return kernel(x, cal)


def apply_calibration(raw: npt.ArrayLike, cal: LegacyCalibration) -> npt.NDArray[np.float64]:
    """Raw ticks ``(..., n_motors)`` (a scalar for one motor) → degrees (DEGREE) / percent (LINEAR).

    Raises:
        JointOutOfRangeError: With LeRobot's message, outside ±270° / −10..110 %.
    """
    return _one_motor(apply_legacy, raw, cal)


def revert_calibration(values: npt.ArrayLike, cal: LegacyCalibration) -> npt.NDArray[np.int64]:
    """Degrees / percent ``(..., n_motors)`` (a scalar for one motor) → raw ticks, ``np.round`` (half to even)."""
    return _one_motor(revert_legacy, values, cal)
