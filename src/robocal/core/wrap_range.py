"""One wrap-aware range tracker: running min/max of positions read modulo a period.

A position that wraps (a Robstride angle every 2π rad or ±4π, a servo's Present_Position every 4096 ticks) is
unwrapped sample to sample: a step larger than half a period is taken as a crossing of the wrap point and
shifted by whole periods, so a sweep through the wrap gives its true, contiguous range instead of
(≈ bottom, ≈ top). The rule is ``step = d − period·floor(d/period + ½)`` for a raw difference ``d``: a step of
exactly half a period counts as going down, as LeRobot's ``(d + half) mod period − half`` does.

The same tracker serves the Robstride/Lite sweep (``period=2π``, ``units="rad"``) and LeRobot's range
recording (``period=resolution``, ``units="ticks"``, fixing huggingface/lerobot#3586).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import numpy.typing as npt

from ..errors import InvalidCalibrationError, ShapeMismatchError
from .arrays import FloatArray

__all__ = ["RangeTracker"]



class RangeTracker:
    """Running min/max of N joint positions that unwraps sample-to-sample jumps across a period.

    Unwrapped values stay on the branch of each joint's first sample. Non-finite samples are ignored per
    joint. Besides the unwrapped extremes it keeps the extremes as read (:attr:`raw_minimum`,
    :attr:`raw_maximum`: what a wrap-blind recorder such as LeRobot 0.6.1 would report).

    Args:
        n_joints: Number of joints N.
        period: Wrap period, in ``units`` (2π for Robstride positions in rad, 4096 for servo ticks).
        units: Unit of the positions and the period, for messages (``"rad"``, ``"ticks"``).
    """

    def __init__(self, n_joints: int, period: float = 2.0 * math.pi, units: str = "rad") -> None:
        if n_joints < 0:
            raise ShapeMismatchError(f"RangeTracker: n_joints {n_joints} must be >= 0")
        if not (math.isfinite(period) and period > 0):
            raise InvalidCalibrationError(f"RangeTracker: period {period} {units} must be finite and > 0")
        self.n_joints = n_joints
        self.period = float(period)
        self.units = units
        self._last = np.full(n_joints, np.nan)  # last raw (wrapped) sample
        self._current = np.full(n_joints, np.nan)  # last unwrapped sample
        self._min = np.full(n_joints, np.inf)
        self._max = np.full(n_joints, -np.inf)
        self._raw_min = np.full(n_joints, np.inf)
        self._raw_max = np.full(n_joints, -np.inf)
        self._count = np.zeros(n_joints, dtype=np.int64)
        self._inv_period = 1.0 / self.period
        self._started = False
        self._fast = 0  # samples added by the fast path (every joint counted)

    def _check(self, s: Any, ndim: int) -> FloatArray:
        arr = np.asarray(s, dtype=np.float64)
        if arr.ndim != ndim or arr.shape[-1] != self.n_joints:
            want = f"({self.n_joints},)" if ndim == 1 else f"(T, {self.n_joints})"
            raise ShapeMismatchError(f"RangeTracker: sample has shape {arr.shape}; expected {want}")
        return arr

    def update(self, sample: npt.ArrayLike) -> None:
        """Add one sample, shape ``(N,)``, in ``units`` (fast path once every joint has a finite sample)."""
        x = self._check(sample, 1)
        if not self._started:
            self.update_many(x[None, :])
            self._started = bool(np.all(self._count > 0))
            return
        d = x - self._last
        if not math.isfinite(d.sum()):
            self.update_many(x[None, :])
            return
        d -= self.period * np.floor(d * self._inv_period + 0.5)
        d += self._current
        np.minimum(self._min, d, out=self._min)
        np.maximum(self._max, d, out=self._max)
        np.minimum(self._raw_min, x, out=self._raw_min)
        np.maximum(self._raw_max, x, out=self._raw_max)
        self._fast += 1
        self._current = d
        self._last = x.copy()

    def update_many(self, samples: npt.ArrayLike) -> None:
        """Add a block of samples, shape ``(T, N)``, in ``units`` (rows in time order)."""
        S = self._check(samples, 2)
        if S.shape[0] == 0:
            return
        finite = np.isfinite(S)
        np.minimum(self._raw_min, np.where(finite, S, np.inf).min(axis=0), out=self._raw_min)
        np.maximum(self._raw_max, np.where(finite, S, -np.inf).max(axis=0), out=self._raw_max)
        last = self._last.copy()
        cur = self._current.copy()
        fresh = ~np.isfinite(last) & finite.any(axis=0)
        if fresh.any():  # a joint's first finite sample starts its branch
            first_row = np.argmax(finite, axis=0)
            first_val = S[first_row, np.arange(self.n_joints)]
            last[fresh] = first_val[fresh]
            cur[fresh] = first_val[fresh]
        if not finite.all():  # forward-fill gaps with the previous finite value
            idx = np.where(finite, np.arange(S.shape[0])[:, None], -1)
            np.maximum.accumulate(idx, axis=0, out=idx)
            S = np.take_along_axis(np.vstack([last[None, :], S]), idx + 1, axis=0)
        d = np.diff(np.vstack([last[None, :], S]), axis=0)
        d = np.nan_to_num(d - self.period * np.floor(d * self._inv_period + 0.5), nan=0.0)
        U = cur[None, :] + np.cumsum(d, axis=0)
        valid = finite
        np.minimum(self._min, np.where(valid, U, np.inf).min(axis=0), out=self._min)
        np.maximum(self._max, np.where(valid, U, -np.inf).max(axis=0), out=self._max)
        self._count += valid.sum(axis=0)
        seen = valid.any(axis=0)
        self._current = np.where(seen, U[-1], cur)
        self._last = np.where(seen, S[-1], last)

    @property
    def count(self) -> npt.NDArray[np.int64]:
        """Finite samples seen per joint, shape ``(N,)``."""
        out: npt.NDArray[np.int64] = self._count + self._fast
        return out

    @property
    def current(self) -> FloatArray:
        """Latest unwrapped position per joint, shape ``(N,)`` (NaN before the first sample)."""
        out: FloatArray = self._current.copy()
        return out

    @property
    def minimum(self) -> FloatArray:
        """Unwrapped minimum per joint, shape ``(N,)`` (NaN before the first sample)."""
        return np.where(self.count > 0, self._min, np.nan)

    @property
    def maximum(self) -> FloatArray:
        """Unwrapped maximum per joint, shape ``(N,)`` (NaN before the first sample)."""
        return np.where(self.count > 0, self._max, np.nan)

    @property
    def raw_minimum(self) -> FloatArray:
        """Smallest sample as read (wrap-blind) per joint, shape ``(N,)`` (NaN before the first sample)."""
        return np.where(self.count > 0, self._raw_min, np.nan)

    @property
    def raw_maximum(self) -> FloatArray:
        """Largest sample as read (wrap-blind) per joint, shape ``(N,)`` (NaN before the first sample)."""
        return np.where(self.count > 0, self._raw_max, np.nan)

    @property
    def sweep(self) -> FloatArray:
        """``maximum − minimum`` per joint, shape ``(N,)`` (0 before the first sample)."""
        return np.where(self.count > 0, self._max - self._min, 0.0)
