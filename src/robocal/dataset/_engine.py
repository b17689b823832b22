"""Per-table and per-file re-calibration engine (pyarrow + numpy).

A vector feature column is a ``fixed_size_list<float32>[D]``; its flat child array is viewed as a numpy
``(N, D)`` array, mapped ``value_old → actual → value_new`` joint by joint, and rebuilt with
``FixedSizeListArray.from_arrays`` using the column's own type, so the Arrow schema (and its HF metadata) is
unchanged. Files are rewritten row group by row group, so one row group per episode stays one per episode.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from concurrent.futures import Future, ThreadPoolExecutor
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import pyarrow as pa
import pyarrow.compute as pc
import pyarrow.parquet as pq
from numpy.typing import NDArray

from ..errors import FileFormatError, InvalidCalibrationError, ShapeMismatchError, UsageError
from ._convention import BoolArray, FloatArray, ValueConvention, check_joint_names
from ._layout import DEFAULT_FEATURES
from ._stats import StatAccumulator, episode_stats, merge_into

NDArrayInt = NDArray[np.int64]

__all__ = [
    "FeaturePlan",
    "FileResult",
    "recalibrate_file",
    "recalibrate_table",
    "recalibrate_table_with_counts",
    "recalibrate_values",
]


@dataclass(frozen=True)
class FeaturePlan:
    """How one feature column is re-calibrated.

    Attributes:
        key: Column name, e.g. ``"action"``.
        joint_names: Joint names in column order, length ``D``.
        old: Convention the values were recorded with, in column order.
        new: Convention to convert to, in column order.
    """

    key: str
    joint_names: tuple[str, ...]
    old: ValueConvention
    new: ValueConvention

    @classmethod
    def build(
        cls, key: str, joint_names: Sequence[str], old: ValueConvention, new: ValueConvention
    ) -> FeaturePlan:
        """Select and reorder ``old`` and ``new`` to the feature's joints.

        Raises:
            JointMismatchError: A calibration does not hold exactly the feature's joints.
        """
        names = tuple(joint_names)
        check_joint_names(names, list(old.joint_names), f"feature {key!r} vs the old calibration")
        check_joint_names(names, list(new.joint_names), f"feature {key!r} vs the new calibration")
        o, n = old.select(names), new.select(names)
        check = getattr(o, "check_target", None)
        if callable(check):
            check(n)
        return cls(key=key, joint_names=names, old=o, new=n)


def feature_convention(
    conv: ValueConvention | Mapping[str, ValueConvention], key: str, role: str
) -> ValueConvention:
    """The convention for feature ``key``: ``conv`` itself, or its entry when it is a per-feature mapping.

    Raises:
        UsageError: The mapping has no entry for ``key``, or the convention is not a ``ValueConvention``.
    """
    if isinstance(conv, Mapping):
        if key not in conv:
            given = ", ".join(map(str, conv)) or "none"
            raise UsageError(f"feature {key!r}: no {role} calibration for it (given for: {given})")
        conv = conv[key]
    if not isinstance(conv, ValueConvention):
        raise UsageError(
            f"feature {key!r}: the {role} calibration is a {type(conv).__name__}; expected a "
            "ValueConvention (e.g. robocal.dataset.lerobot.LeRobotConvention)"
        )
    return conv


def recalibrate_values(
    values: FloatArray, old: ValueConvention, new: ValueConvention
) -> tuple[FloatArray, BoolArray]:
    """Map stored values through the actual encoder position.

    Args:
        values: Shape ``(N, D)``, stored values under ``old`` (columns in ``old.joint_names`` order).
        old: Convention the values were recorded with.
        new: Convention to convert to (same joint order).

    Returns:
        ``(new_values (N, D), out_of_range (N, D))``, the mask marks positions outside ``new``'s range.
    """
    v = np.asarray(values, dtype=np.float64)
    if v.ndim == 2 and v.shape[0] > _LUT_MIN_ROWS:
        uniq = _unique_columns(v)
        if uniq is not None:
            # recorded values come from whole ticks: map each distinct value of a column once
            table, idx = uniq
            table_values, table_mask = new.from_actual(old.to_actual(table))
            out_values = np.empty(v.shape, dtype=np.float64)
            out_mask = np.empty(v.shape, dtype=np.bool_)
            for j, ix in enumerate(idx):
                out_values[:, j] = np.take(table_values[:, j], ix)
                out_mask[:, j] = np.take(table_mask[:, j], ix)
            return out_values, out_mask
    actual = old.to_actual(v)
    if getattr(old, "integer_ticks", False) and actual.ndim == 2 and actual.shape[0] > _LUT_MIN_ROWS:
        lo = actual.min(axis=0)
        span = int((actual.max(axis=0) - lo).max()) + 1
        if span <= _LUT_MAX_SPAN:
            # whole ticks: map each distinct tick once and look the frames up (same values, fewer ops)
            grid = lo[None, :] + np.arange(span, dtype=np.float64)[:, None]
            grid_values, grid_mask = new.from_actual(grid)
            idx = (actual - lo).astype(np.intp)
            return np.take_along_axis(grid_values, idx, axis=0), np.take_along_axis(grid_mask, idx, axis=0)
    return new.from_actual(actual)


_LUT_MIN_ROWS = 8192
_LUT_MAX_SPAN = 1 << 16


def _unique_columns(values: FloatArray) -> tuple[FloatArray, list[NDArray[np.intp]]] | None:
    """Distinct values per column: ``(table (K, D), [index (N,)] * D)``, ``values[:, j] = table[index[j], j]``.

    Conventions are per-joint maps, so mapping ``table`` and looking the frames up gives the same numbers as
    mapping every frame. Distinct values are found with Arrow's hash-based ``dictionary_encode``. Returns
    ``None`` when a column has too many distinct values for this to pay off.
    """
    n, d = values.shape
    indices: list[NDArray[np.intp]] = []
    uniques: list[FloatArray] = []
    for j in range(d):
        enc = pc.dictionary_encode(pa.array(values[:, j]))
        dictionary = np.asarray(enc.dictionary.to_numpy(), dtype=np.float64)
        if dictionary.size * 8 > n:
            return None
        uniques.append(dictionary)
        indices.append(np.asarray(enc.indices.to_numpy(), dtype=np.intp))
    k = max(u.size for u in uniques)
    table = np.empty((k, d), dtype=np.float64)
    for j, u in enumerate(uniques):
        table[: u.size, j] = u
        table[u.size :, j] = u[0]
    return table, indices


def _column_values(column: pa.ChunkedArray | pa.Array, key: str) -> tuple[FloatArray, pa.DataType]:
    arr = column.combine_chunks() if isinstance(column, pa.ChunkedArray) else column
    typ = arr.type
    if not (pa.types.is_fixed_size_list(typ) and pa.types.is_floating(typ.value_type)):
        raise FileFormatError(f"column {key!r}: expected fixed_size_list<float>, found {typ}")
    if arr.null_count:
        raise FileFormatError(f"column {key!r}: {arr.null_count} null rows; expected a value in every frame")
    flat = arr.flatten()  # respects slicing, unlike .values
    if flat.null_count:
        raise FileFormatError(f"column {key!r}: {flat.null_count} null entries; expected finite numbers")
    d = typ.list_size
    values = np.asarray(flat.to_numpy(zero_copy_only=False), dtype=np.float64).reshape(-1, d)
    finite = np.isfinite(values)
    if not finite.all():
        row, col = np.argwhere(~finite)[0]
        raise FileFormatError(
            f"column {key!r}: {int((~finite).sum())} NaN or inf entries (first at row {row}, entry {col}); "
            "expected finite numbers"
        )
    return values, typ


def recalibrate_table_with_counts(
    table: pa.Table, plans: Sequence[FeaturePlan]
) -> tuple[pa.Table, dict[str, NDArrayInt], dict[str, NDArray[Any]]]:
    """Re-calibrate the planned feature columns of one table.

    Args:
        table: Frames, with each planned feature a ``fixed_size_list<float>[D]`` column.
        plans: One :class:`FeaturePlan` per feature to convert.

    Returns:
        ``(table, out_of_range, new_values)``: the new table (same schema), per feature the count of values
        outside the new calibrated range per joint (shape ``(D,)``), and per feature the stored new values
        ``(N, D)`` in the column's dtype (for statistics).

    Raises:
        FileFormatError: A column is missing, not a fixed-size list or has nulls.
        ShapeMismatchError: A column's width differs from the feature's number of joints.
    """
    counts: dict[str, NDArrayInt] = {}
    stored: dict[str, NDArray[Any]] = {}
    out = table
    for plan in plans:
        idx = table.schema.get_field_index(plan.key)
        if idx < 0:
            raise FileFormatError(f"column {plan.key!r} is missing from the data table")
        values, typ = _column_values(table.column(idx), plan.key)
        if values.shape[1] != len(plan.joint_names):
            raise ShapeMismatchError(
                f"column {plan.key!r} has {values.shape[1]} entries per frame; "
                f"expected {len(plan.joint_names)} ({', '.join(plan.joint_names)})"
            )
        new_values, mask = recalibrate_values(values, plan.old, plan.new)
        np_type = pa.array([], type=typ.value_type).to_numpy(zero_copy_only=False).dtype  # no pandas needed
        cast = np.ascontiguousarray(new_values, dtype=np_type)
        child = pa.array(cast.reshape(-1), type=typ.value_type)
        new_col = pa.FixedSizeListArray.from_arrays(child, type=typ)
        out = out.set_column(idx, table.schema.field(idx), new_col)
        counts[plan.key] = mask.sum(axis=0).astype(np.int64)
        stored[plan.key] = cast
    return out, counts, stored


def recalibrate_table(
    table: pa.Table,
    old: ValueConvention | Mapping[str, ValueConvention],
    new: ValueConvention | Mapping[str, ValueConvention],
    *,
    features: Mapping[str, Sequence[str]] | None = None,
) -> pa.Table:
    """Re-calibrate the joint-position features of a table of frames.

    Args:
        table: Frames (e.g. one row group of a LeRobot data file).
        old: The recording's convention, one for all features or one per feature key.
        new: The target convention, one for all features or one per feature key.
        features: Feature key → joint names in column order. Default: every key of ``old`` when it is a
            mapping, else ``observation.state`` and ``action`` (those present) with ``old.joint_names``.

    Returns:
        A table with the same schema and the converted feature columns.

    Raises:
        UsageError: ``table`` is not a table, a calibration is not a convention or lacks a feature, or no
            feature is given and neither default column exists.
        JointMismatchError: A feature's joints differ from a calibration's.
        FileFormatError: A feature column is missing, not a ``fixed_size_list<float>`` or holds NaN.
    """
    if not isinstance(table, pa.Table):
        raise UsageError(f"recalibrate_table: expected a pyarrow.Table, got {type(table).__name__}")
    if features is None:
        if isinstance(old, Mapping):
            features = {k: feature_convention(old, k, "old").joint_names for k in old}
        else:
            keys = [k for k in DEFAULT_FEATURES if k in table.schema.names]
            if not keys:
                raise UsageError(
                    f"recalibrate_table: the table has none of the columns {', '.join(DEFAULT_FEATURES)}; "
                    f"name the features (columns: {', '.join(table.schema.names) or 'none'})"
                )
            features = dict.fromkeys(keys, feature_convention(old, keys[0], "old").joint_names)
    plans = [
        FeaturePlan.build(k, names, feature_convention(old, k, "old"), feature_convention(new, k, "new"))
        for k, names in features.items()
    ]
    out, _, _ = recalibrate_table_with_counts(table, plans)
    return out


@dataclass
class FileResult:
    """What re-calibrating one data file produced.

    Attributes:
        path: File path relative to the dataset root.
        frames: Number of frames (rows).
        row_groups: Number of row groups written (equal to the source's).
        out_of_range: Per feature, count per joint of values outside the new calibrated range, shape ``(D,)``.
        episode_stats: Episode index → feature → accumulated statistics of the new values.
    """

    path: str
    frames: int = 0
    row_groups: int = 0
    out_of_range: dict[str, NDArrayInt] = field(default_factory=dict)
    episode_stats: dict[int, dict[str, StatAccumulator]] = field(default_factory=dict)


def _compression_of(meta: pq.FileMetaData) -> str:
    if meta.num_row_groups and meta.num_columns:
        comp = str(meta.row_group(0).column(0).compression).lower()
        if comp in ("snappy", "gzip", "brotli", "zstd", "lz4", "none", "uncompressed"):
            return "none" if comp == "uncompressed" else comp
    return "snappy"


def _batches(sizes: Sequence[int], batch_rows: int) -> list[list[int]]:
    """Group consecutive row groups into batches of about ``batch_rows`` rows."""
    out: list[list[int]] = []
    cur: list[int] = []
    rows = 0
    for g, n in enumerate(sizes):
        if cur and rows + n > batch_rows:
            out.append(cur)
            cur, rows = [], 0
        cur.append(g)
        rows += n
    if cur:
        out.append(cur)
    return out


def recalibrate_file(
    src: str | Path,
    dst: str | Path,
    plans: Sequence[FeaturePlan],
    rel_path: str = "",
    *,
    batch_rows: int = 131072,
) -> FileResult:
    """Re-calibrate one Parquet data file row group by row group.

    The output has the source's Arrow schema (including the ``huggingface`` metadata), the same row groups
    and the same compression.

    Args:
        src: Source Parquet file.
        dst: Destination file (its folder must exist; it is overwritten).
        plans: Features to convert.
        rel_path: Path reported in results and errors (default: ``src``).
        batch_rows: Consecutive row groups are read and converted together up to about this many rows
            (fewer numpy calls); each is still written as its own row group.

    Returns:
        Frame count, out-of-range counts and per-episode statistics.

    Raises:
        FileFormatError: The file cannot be read as Parquet or a column is malformed.
    """
    name = rel_path or str(src)
    result = FileResult(path=name)
    try:
        pf = pq.ParquetFile(src)
        schema = pf.schema_arrow
    except (pa.ArrowException, OSError) as exc:
        raise FileFormatError(f"data file {name}: cannot read Parquet ({exc})") from None
    for plan in plans:
        if schema.get_field_index(plan.key) < 0:
            raise FileFormatError(f"data file {name}: column {plan.key!r} is missing")
        result.out_of_range[plan.key] = np.zeros(len(plan.joint_names), dtype=np.int64)
    has_episode = schema.get_field_index("episode_index") >= 0
    meta = pf.metadata
    sizes = [meta.row_group(g).num_rows for g in range(meta.num_row_groups)]
    try:
        with (
            pq.ParquetWriter(dst, schema=schema, compression=_compression_of(meta)) as writer,
            ThreadPoolExecutor(max_workers=1) as write_thread,  # writes overlap the next batch's maths
        ):
            pending: Future[None] | None = None

            def write(table: pa.Table, batch: list[int]) -> None:
                offset = 0
                for g in batch:  # one output row group per source row group
                    writer.write_table(table.slice(offset, sizes[g]), row_group_size=max(sizes[g], 1))
                    offset += sizes[g]

            for batch in _batches(sizes, batch_rows):
                table = pf.read_row_groups(batch) if len(batch) > 1 else pf.read_row_group(batch[0])
                try:
                    new_table, counts, stored = recalibrate_table_with_counts(table, plans)
                except (FileFormatError, InvalidCalibrationError) as exc:
                    raise FileFormatError(
                        f"data file {name}, row groups {batch[0]}-{batch[-1]}: {exc}"
                    ) from None
                if pending is not None:
                    pending.result()
                pending = write_thread.submit(write, new_table, batch)
                result.row_groups += len(batch)
                result.frames += new_table.num_rows
                for key, c in counts.items():
                    result.out_of_range[key] += c
                if has_episode and new_table.num_rows:
                    episodes = np.asarray(new_table.column("episode_index").to_numpy(), dtype=np.int64)
                    merge_into(result.episode_stats, episode_stats(episodes, stored, keep_edges=True))
                    # an episode may continue in the next batch or file: keep the frames of the file's
                    # first and of the latest episode only (exact quantiles when the parts are joined)
                    edges = {int(episodes[-1]), next(iter(result.episode_stats))}
                    for ep, accs in result.episode_stats.items():
                        if ep not in edges:
                            for key, a in accs.items():
                                accs[key] = a.without_samples()
            if pending is not None:
                pending.result()
    except (pa.ArrowException, OSError) as exc:
        raise FileFormatError(f"data file {name}: cannot read or write Parquet ({exc})") from None
    return result
