"""Feature statistics in LeRobot's layout (``meta/stats.json`` and per-episode ``stats/<feature>/<stat>``).

LeRobot stores, per vector feature, lists of length ``D`` for ``min``, ``max``, ``mean``, ``std`` and
the quantiles ``q01 q10 q50 q90 q99`` (newer versions), plus ``count`` as a one-element list. Per-episode
statistics are exact; the dataset statistics combine them the way LeRobot's ``aggregate_stats`` does:
min of mins, max of maxes, count-weighted mean, pooled variance, and count-weighted means of the
per-episode quantiles.
"""

from __future__ import annotations

import math
import re
from collections.abc import Iterable, Mapping
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

__all__ = [
    "QUANTILES",
    "StatAccumulator",
    "episode_stats",
    "is_known_stat",
    "merge_all",
]

FloatArray = NDArray[np.float64]

QUANTILES: dict[str, float] = {"q01": 0.01, "q10": 0.10, "q50": 0.50, "q90": 0.90, "q99": 0.99}
"""Quantile statistics LeRobot writes, name → fraction."""

_BASIC = ("min", "max", "mean", "std", "count")
_Q_RE = re.compile(r"^q(\d\d)$")


def is_known_stat(name: str) -> bool:
    """Whether :meth:`StatAccumulator.as_dict` can produce statistic ``name``."""
    return name in _BASIC or bool(_Q_RE.match(name))


@dataclass(frozen=True, eq=False)
class StatAccumulator:
    """Mergeable statistics of one feature over a set of frames.

    Attributes:
        count: Number of frames.
        min: Shape ``(D,)``.
        max: Shape ``(D,)``.
        mean: Shape ``(D,)``.
        m2: Sum of squared deviations from the mean, shape ``(D,)``.
        quantiles: Fraction → quantile values ``(D,)``; exact for one chunk, count-weighted after merges.
    """

    count: int
    min: FloatArray
    max: FloatArray
    mean: FloatArray
    m2: FloatArray
    quantiles: Mapping[float, FloatArray]

    @classmethod
    def of(cls, values: FloatArray, fractions: Iterable[float] = QUANTILES.values()) -> StatAccumulator:
        """Statistics of ``values``, shape ``(N, D)`` with ``N ≥ 1``."""
        v = np.asarray(values, dtype=np.float64)
        mean = v.mean(axis=0)
        fr = sorted(set(fractions))
        qs = np.quantile(v, fr, axis=0) if fr else np.empty((0, v.shape[1]))
        return cls(
            count=int(v.shape[0]),
            min=v.min(axis=0),
            max=v.max(axis=0),
            mean=mean,
            m2=((v - mean) ** 2).sum(axis=0),
            quantiles={f: qs[i] for i, f in enumerate(fr)},
        )

    def merge(self, other: StatAccumulator) -> StatAccumulator:
        """Combine with the statistics of a disjoint set of frames (Chan's parallel variance)."""
        n = self.count + other.count
        delta = other.mean - self.mean
        mean = self.mean + delta * (other.count / n)
        m2 = self.m2 + other.m2 + delta**2 * (self.count * other.count / n)
        qs = {
            f: (self.quantiles[f] * self.count + other.quantiles[f] * other.count) / n
            for f in self.quantiles
            if f in other.quantiles
        }
        return StatAccumulator(
            count=n,
            min=np.minimum(self.min, other.min),
            max=np.maximum(self.max, other.max),
            mean=mean,
            m2=m2,
            quantiles=qs,
        )

    @property
    def std(self) -> FloatArray:
        """Population standard deviation, shape ``(D,)`` (numpy's default, as LeRobot uses)."""
        out: FloatArray = np.sqrt(np.maximum(self.m2 / self.count, 0.0))
        return out

    def get(self, name: str) -> list[float] | list[int] | None:
        """One statistic as LeRobot stores it (a list), or ``None`` if not computable."""
        if name == "count":
            return [self.count]
        if name in ("min", "max", "mean"):
            return [float(x) for x in getattr(self, name)]
        if name == "std":
            return [float(x) for x in self.std]
        m = _Q_RE.match(name)
        if m:
            f = int(m.group(1)) / 100.0
            for key, val in self.quantiles.items():
                if math.isclose(key, f):
                    return [float(x) for x in val]
        return None


def episode_stats(
    episode_index: NDArray[np.int64], values: Mapping[str, FloatArray]
) -> dict[int, dict[str, StatAccumulator]]:
    """Statistics per episode and feature.

    Args:
        episode_index: Shape ``(N,)``, the episode of each frame.
        values: Feature → values ``(N, D)``.

    Returns:
        Episode → feature → statistics.
    """
    out: dict[int, dict[str, StatAccumulator]] = {}
    if episode_index.size == 0:
        return out
    if episode_index[0] == episode_index[-1] and np.all(episode_index == episode_index[0]):
        groups = [(int(episode_index[0]), slice(None))]
    else:
        eps = np.unique(episode_index)
        groups = [(int(e), np.flatnonzero(episode_index == e)) for e in eps]  # type: ignore[misc]
    for ep, sel in groups:
        out[ep] = {key: StatAccumulator.of(v[sel]) for key, v in values.items()}
    return out


def merge_all(accs: Iterable[StatAccumulator]) -> StatAccumulator | None:
    """Merge many accumulators (``None`` if there are none)."""
    total: StatAccumulator | None = None
    for a in accs:
        total = a if total is None else total.merge(a)
    return total
