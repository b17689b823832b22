"""Per-joint summary of a dataset's calibrated features, flagging signs of a wrong calibration.

Two signs are flagged per joint: *full-turn jumps* (two consecutive frames of one episode more than half an
encoder turn apart in value units, which a real joint cannot do in one frame) and values outside the
calibrated range (from the calibration when one is given, else from the normalisation mode: beyond ±180° in
degrees mode).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq

from ..core.arrays import FloatArray
from ..errors import FileFormatError
from ._convention import ValueConvention
from ._layout import is_position_entry, read_layout
from .teleop_frames import episode_numbers

__all__ = ["InspectReport", "JointSummary", "inspect_dataset"]

_MODE_TURN = {"degrees": 360.0, "range_m100_100": 200.0, "range_0_100": 100.0}
"""Without a calibration: value span of one turn assumed per mode (a jump of half of it is flagged)."""
_MODE_RANGE = {"degrees": (-180.0, 180.0), "range_m100_100": (-100.0, 100.0), "range_0_100": (0.0, 100.0)}


@dataclass(frozen=True)
class JointSummary:
    """Statistics and flags of one joint of one feature.

    Attributes:
        feature: Feature key.
        joint: Joint name.
        min: Smallest value (value units).
        max: Largest value.
        mean: Mean value.
        jumps: Frame-to-frame jumps of more than half a turn within an episode.
        out_of_range: Values outside the calibrated range (0 when no range is known).
        range_lo: Lower end of the calibrated range used, or ``None``.
        range_hi: Upper end of the calibrated range used, or ``None``.
        non_finite: NaN or infinite values, and null rows (left out of min, max and mean; those are NaN without any
            finite value).
    """

    feature: str
    joint: str
    min: float
    max: float
    mean: float
    jumps: int
    out_of_range: int
    range_lo: float | None
    range_hi: float | None
    non_finite: int = 0

    @property
    def flagged(self) -> bool:
        """Whether this joint shows a sign of a wrong calibration (or holds NaN / infinite values)."""
        return self.jumps > 0 or self.out_of_range > 0 or self.non_finite > 0


@dataclass(frozen=True)
class InspectReport:
    """Result of :func:`inspect_dataset`.

    Attributes:
        root: Dataset root.
        frames: Number of frames read.
        joints: One summary per feature and joint.
    """

    root: Path
    frames: int
    joints: tuple[JointSummary, ...]

    @property
    def flagged(self) -> tuple[JointSummary, ...]:
        """Joints with a jump or out-of-range values."""
        return tuple(j for j in self.joints if j.flagged)


def _limits(
    names: Sequence[str], conv: ValueConvention | None, modes: Mapping[str, str] | None
) -> tuple[FloatArray | None, FloatArray | None, FloatArray]:
    d = len(names)
    turn = np.full(d, np.inf)
    lo: FloatArray | None = None
    hi: FloatArray | None = None
    if conv is not None:
        # entries that are not joint positions (e.g. "x.vel") get no range and no turn
        idx = [i for i, n in enumerate(names) if n in conv.joint_names or is_position_entry(n)]
        sel = conv.select([names[i] for i in idx])
        turn[idx] = np.asarray(sel.full_turn(), dtype=np.float64)
        rng = sel.value_range()
        if rng is not None:
            lo, hi = np.full(d, -np.inf), np.full(d, np.inf)
            lo[idx] = np.asarray(rng[0], dtype=np.float64)
            hi[idx] = np.asarray(rng[1], dtype=np.float64)
    elif modes:
        lo_l, hi_l = [], []
        for i, n in enumerate(names):
            mode = modes.get(n)
            if mode in _MODE_TURN:
                turn[i] = _MODE_TURN[mode]
            r = _MODE_RANGE.get(mode or "", (-np.inf, np.inf))
            lo_l.append(r[0])
            hi_l.append(r[1])
        lo, hi = np.array(lo_l), np.array(hi_l)
    return lo, hi, turn


def inspect_dataset(
    root: str | Path,
    *,
    features: Sequence[str] | None = None,
    calibration: ValueConvention | None = None,
    modes: Mapping[str, str] | None = None,
    tolerance: float = 1e-4,
) -> InspectReport:
    """Summarise the calibrated features of a LeRobot v3 dataset per joint.

    Args:
        root: Dataset root.
        features: Feature keys (default ``observation.state`` and ``action``, those present).
        calibration: The dataset's calibration, for the calibrated range and the size of a turn.
        modes: Joint → normalisation mode, used when no calibration is given.
        tolerance: Slack on the range limits, value units.

    Returns:
        Per-joint min/max/mean, jump and out-of-range counts.

    Raises:
        FileFormatError: A malformed dataset or data file.
        UsageError: Unknown feature.
    """
    layout = read_layout(root)
    feats = layout.select(features)
    plans = [(f, *_limits(f.joint_names, calibration, modes)) for f in feats]
    d_of = {f.key: f.size for f in feats}
    acc: dict[str, dict[str, FloatArray]] = {
        f.key: {
            "min": np.full(f.size, np.inf),
            "max": np.full(f.size, -np.inf),
            "sum": np.zeros(f.size),
            "jumps": np.zeros(f.size),
            "oor": np.zeros(f.size),
            "finite": np.zeros(f.size),
        }
        for f in feats
    }
    frames = 0
    for rel in layout.data_files:
        try:
            pf = pq.ParquetFile(layout.root / rel)
            cols = [f.key for f in feats] + (
                ["episode_index"] if "episode_index" in pf.schema_arrow.names else []
            )
            for g in range(pf.metadata.num_row_groups):
                table = pf.read_row_group(g, columns=cols)
                frames += table.num_rows
                eps = (
                    episode_numbers(table, rel)
                    if "episode_index" in cols
                    else np.zeros(table.num_rows, dtype=np.int64)
                )
                same_ep = eps[1:] == eps[:-1]
                for feat, lo, hi, turn in plans:
                    arr = table.column(feat.key).combine_chunks()
                    if not pa.types.is_fixed_size_list(arr.type) or arr.type.list_size != d_of[feat.key]:
                        raise FileFormatError(
                            f"data file {rel}: column {feat.key!r} is {arr.type}; expected "
                            f"fixed_size_list<float>[{d_of[feat.key]}]"
                        )
                    # a damaged file's values may not fit a float64 (or be inf / NaN): counted below as not
                    # finite, never a numpy warning
                    with np.errstate(invalid="ignore", over="ignore"):
                        flat = np.asarray(arr.flatten().to_numpy(zero_copy_only=False), dtype=np.float64)
                    # a null row (a frame with no value) has no values in the flattened column: NaN, not finite
                    v = np.full((len(arr), d_of[feat.key]), np.nan)
                    v[np.asarray(arr.is_valid())] = flat.reshape(-1, d_of[feat.key])
                    if v.shape[0] == 0:
                        continue
                    a = acc[feat.key]
                    finite = np.isfinite(v)
                    a["finite"] += finite.sum(axis=0)
                    a["min"] = np.minimum(a["min"], np.where(finite, v, np.inf).min(axis=0))
                    a["max"] = np.maximum(a["max"], np.where(finite, v, -np.inf).max(axis=0))
                    a["sum"] += np.where(finite, v, 0.0).sum(axis=0)
                    with np.errstate(invalid="ignore", over="ignore"):  # inf − inf in a damaged file
                        jump = (np.abs(np.diff(v, axis=0)) > 0.5 * turn) & same_ep[:, None]
                    a["jumps"] += jump.sum(axis=0)
                    if lo is not None and hi is not None:
                        a["oor"] += ((v < lo - tolerance) | (v > hi + tolerance)).sum(axis=0)
        except (pa.ArrowException, OSError) as exc:
            raise FileFormatError(f"data file {rel}: cannot read Parquet ({exc})") from None
    out: list[JointSummary] = []
    for feat, lo, hi, _ in plans:
        a = acc[feat.key]
        for i, name in enumerate(feat.joint_names):
            n_finite = int(a["finite"][i])
            out.append(
                JointSummary(
                    feature=feat.key,
                    joint=name,
                    min=float(a["min"][i]) if n_finite else float("nan"),
                    max=float(a["max"][i]) if n_finite else float("nan"),
                    mean=float(a["sum"][i] / n_finite) if n_finite else float("nan"),
                    jumps=int(a["jumps"][i]),
                    out_of_range=int(a["oor"][i]),
                    range_lo=None if lo is None or not np.isfinite(lo[i]) else float(lo[i]),
                    range_hi=None if hi is None or not np.isfinite(hi[i]) else float(hi[i]),
                    non_finite=frames - n_finite,
                )
            )
    return InspectReport(root=layout.root, frames=frames, joints=tuple(out))
