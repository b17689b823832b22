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
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, replace

import numpy as np
from numpy.typing import NDArray

from ..core.arrays import FloatArray

__all__ = [
    "QUANTILES",
    "StatAccumulator",
    "episode_stats",
    "is_known_stat",
    "merge_all",
    "merge_into",
]


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
        samples: The frames themselves ``(N, D)``, kept for a part of an episode that may continue in the
            next batch or file, so that :meth:`join` gives the whole episode's exact quantiles.
    """

    count: int
    min: FloatArray
    max: FloatArray
    mean: FloatArray
    m2: FloatArray
    quantiles: Mapping[float, FloatArray]
    samples: FloatArray | None = None

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

    def join(self, other: StatAccumulator) -> StatAccumulator:
        """Combine two parts of one episode: exact (samples kept) when both kept their samples, else :meth:`merge`."""
        if self.samples is None or other.samples is None:
            return self.merge(other)
        samples = np.concatenate((self.samples, other.samples))
        return replace(StatAccumulator.of(samples, self.quantiles), samples=samples)

    def without_samples(self) -> StatAccumulator:
        """The same statistics without the kept frames."""
        return self if self.samples is None else replace(self, samples=None)

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


def _sorted_quantiles(srt: FloatArray, fractions: Sequence[float]) -> FloatArray:
    """Quantiles of data sorted along axis 1 (``(E, L, D)`` → ``(Q, E, D)``), numpy's ``linear`` method.

    Sorting once is much faster than ``np.quantile``'s partitions along a middle axis; the interpolation is
    numpy's own formula, so the numbers equal ``np.quantile(..., axis=1)``.
    """
    n = srt.shape[1]
    out = np.empty((len(fractions), srt.shape[0], srt.shape[2]), dtype=np.float64)
    for i, f in enumerate(fractions):
        pos = f * (n - 1)
        lo = int(np.floor(pos))
        hi = min(lo + 1, n - 1)
        t = pos - lo
        a = srt[:, lo, :].astype(np.float64)
        b = srt[:, hi, :].astype(np.float64)
        diff = b - a
        out[i] = b - diff * (1 - t) if t >= 0.5 else a + diff * t
    return out


def _segment_stats(
    v: FloatArray, starts: NDArray[np.int64], lengths: NDArray[np.int64], fractions: Sequence[float]
) -> list[StatAccumulator]:
    """Statistics of consecutive row segments of ``v`` ``(N, D)`` in a few vectorised calls.

    ``v`` may be float32 (the stored values): order statistics are exact in it, sums are taken in float64.
    """
    mins = np.minimum.reduceat(v, starts, axis=0).astype(np.float64)
    maxs = np.maximum.reduceat(v, starts, axis=0).astype(np.float64)
    means = np.add.reduceat(v, starts, axis=0, dtype=np.float64) / lengths[:, None]
    dev = v - np.repeat(means, lengths, axis=0)
    m2s = np.add.reduceat(dev * dev, starts, axis=0)
    fr = sorted(set(fractions))
    if fr and np.all(lengths == lengths[0]):
        srt = np.sort(v.reshape(len(starts), int(lengths[0]), v.shape[1]), axis=1)  # (E, L, D)
        qs = _sorted_quantiles(srt, fr)  # (Q, E, D)
        qlist = [{f: qs[i, e] for i, f in enumerate(fr)} for e in range(len(starts))]
    else:
        qlist = []
        for s0, n in zip(starts, lengths, strict=True):
            q: FloatArray = _sorted_quantiles(np.sort(v[s0 : s0 + n], axis=0)[None], fr)[:, 0]
            qlist.append({f: q[i] for i, f in enumerate(fr)})
    return [
        StatAccumulator(
            count=int(lengths[e]), min=mins[e], max=maxs[e], mean=means[e], m2=m2s[e], quantiles=qlist[e]
        )
        for e in range(len(starts))
    ]


def episode_stats(
    episode_index: NDArray[np.int64],
    values: Mapping[str, FloatArray],
    fractions: Sequence[float] = tuple(QUANTILES.values()),
    *,
    keep_edges: bool = False,
) -> dict[int, dict[str, StatAccumulator]]:
    """Statistics per episode and feature.

    Args:
        episode_index: Shape ``(N,)``, the episode of each frame (frames of one episode may be split in
            several runs; their statistics are joined).
        values: Feature → values ``(N, D)``.
        fractions: Quantile fractions to compute.
        keep_edges: Keep the frames of the first and the last episode run (they may continue in the
            previous or next batch), so that joining the parts gives exact quantiles.

    Returns:
        Episode → feature → statistics.
    """
    out: dict[int, dict[str, StatAccumulator]] = {}
    n = episode_index.size
    if n == 0:
        return out
    starts = np.concatenate(([0], np.flatnonzero(episode_index[1:] != episode_index[:-1]) + 1)).astype(
        np.int64
    )
    lengths = np.diff(np.concatenate((starts, [n]))).astype(np.int64)
    eps = episode_index[starts]
    per_key = {key: _segment_stats(np.asarray(v), starts, lengths, fractions) for key, v in values.items()}
    if keep_edges:
        for key, accs in per_key.items():
            for i in {0, len(starts) - 1}:
                seg = np.array(values[key][starts[i] : starts[i] + lengths[i]])  # a copy, not a view
                accs[i] = replace(accs[i], samples=seg)
    for i, ep in enumerate(eps.tolist()):
        merge_into(out, {int(ep): {key: accs[i] for key, accs in per_key.items()}})
    return out


def merge_into(
    dest: dict[int, dict[str, StatAccumulator]], parts: Mapping[int, Mapping[str, StatAccumulator]]
) -> None:
    """Join per-episode statistics ``parts`` into ``dest`` (episode → feature → statistics), in order."""
    for ep, accs in parts.items():
        d = dest.setdefault(ep, {})
        for key, a in accs.items():
            d[key] = d[key].join(a) if key in d else a


def merge_all(accs: Iterable[StatAccumulator]) -> StatAccumulator | None:
    """Merge many accumulators (``None`` if there are none)."""
    total: StatAccumulator | None = None
    for a in accs:
        total = a if total is None else total.merge(a)
    return total
