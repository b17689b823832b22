"""Checks shared by the LeRobot kernels: real-number arrays, whole ticks, resolutions (pure numpy)."""

from __future__ import annotations

from typing import Any

import numpy as np
import numpy.typing as npt

from ...errors import InvalidCalibrationError, ShapeMismatchError
from ..arrays import FloatArray, IntArray


def _check_resolution(resolution: int) -> int:
    if isinstance(resolution, bool) or not isinstance(resolution, (int, np.integer)) or resolution < 2:
        raise InvalidCalibrationError(f"resolution {resolution!r}: expected ticks per turn, an int >= 2")
    return int(resolution)


_NUMERIC_KINDS = "iuf"
_KIND_NAMES = {
    "b": "booleans",
    "c": "complex numbers",
    "M": "datetime64 values",
    "m": "timedelta64 values",
    "U": "strings",
    "S": "byte strings",
    "V": "structured values",
}


def _as_float_array(x: npt.ArrayLike, what: str) -> FloatArray:
    """``x`` as float64, or an InvalidCalibrationError naming ``what`` and what was found.

    Only real numbers are taken (ints, floats, numpy integer/float arrays). Refused: strings (also number
    strings such as ``"1500"``), booleans, complex numbers, datetime64/timedelta64, ``None`` (reported as a
    missing value), ragged lists and any other object.
    """
    try:
        with np.errstate(invalid="ignore"):
            probe = np.asarray(x)
    except (TypeError, ValueError, OverflowError):
        raise InvalidCalibrationError(f"{what} is not an array of numbers: {x!r:.80}") from None
    kind = probe.dtype.kind
    if kind == "O":
        flat = probe.reshape(-1)
        missing = [i for i, v in enumerate(flat) if v is None]
        if missing:
            where = f" (element {missing[0]})" if probe.ndim else ""
            raise InvalidCalibrationError(f"{what} has a missing value (None){where}; expected numbers")
        for v in flat:
            if isinstance(v, (bool, np.bool_)) or not isinstance(v, (int, float, np.integer, np.floating)):
                raise InvalidCalibrationError(
                    f"{what} contains {type(v).__name__} {v!r:.40}; expected real numbers"
                )
        try:
            probe = probe.astype(np.float64)
        except (TypeError, ValueError, OverflowError):
            raise InvalidCalibrationError(f"{what} is not an array of numbers: {x!r:.80}") from None
    elif kind not in _NUMERIC_KINDS:
        name = _KIND_NAMES.get(kind, f"dtype {probe.dtype}")
        raise InvalidCalibrationError(f"{what} contains {name} ({x!r:.60}); expected real numbers")
    with np.errstate(invalid="ignore", over="ignore"):
        arr: FloatArray = probe.astype(np.float64, copy=False)  # never written to by the kernels
    return arr


def _to_ticks(x: npt.NDArray[np.floating[Any]], what: str) -> IntArray:
    """Whole-valued float ticks → int64, refusing values an int64 cannot hold (instead of wrapping)."""
    if x.size and (x.max() >= 2.0**63 or x.min() <= -(2.0**63)):  # |x| >= 2**63, without a temporary array
        raise InvalidCalibrationError(
            f"{what}: the resulting ticks exceed the int64 range (largest |value| {np.max(np.abs(x)):g})"
        )
    return x.astype(np.int64)


def _check_values(x: npt.ArrayLike, n: int, what: str) -> FloatArray:
    arr = _as_float_array(x, what)
    if arr.ndim == 0 or arr.shape[-1] != n:
        raise ShapeMismatchError(f"{what} has shape {arr.shape}; expected (..., {n}) for {n} motor(s)")
    if not np.all(np.isfinite(arr)):
        raise InvalidCalibrationError(f"{what} contains NaN or inf; expected finite numbers")
    return arr
