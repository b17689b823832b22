"""Per-table re-calibration engine (pyarrow + numpy); whole Parquet files are :mod:`._file`'s job.

A vector feature column is a ``fixed_size_list<float32>[D]``; its flat child array is viewed as a numpy
``(N, D)`` array, mapped ``value_old → actual → value_new`` joint by joint, and rebuilt with
``FixedSizeListArray.from_arrays`` using the column's own type, so the Arrow schema (and its HF metadata) is
unchanged.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
import pyarrow as pa
import pyarrow.compute as pc
from numpy.typing import NDArray

from ..core.arrays import BoolArray, FloatArray
from ..errors import (
    FileFormatError,
    JointMismatchError,
    ShapeMismatchError,
    UsageError,
)
from ._convention import Conventions, ValueConvention
from ._layout import DEFAULT_FEATURES, is_position_entry, joint_name

NDArrayInt = NDArray[np.int64]

__all__ = [
    "FeaturePlan",
    "recalibrate_table",
    "recalibrate_table_with_counts",
    "recalibrate_values",
]


@dataclass(frozen=True)
class FeaturePlan:
    """How one feature column is re-calibrated.

    Attributes:
        key: Column name, e.g. ``"action"``.
        joint_names: Names of the converted joints, in column order (the joint-position entries).
        old: Convention the values were recorded with, restricted to ``joint_names`` in that order.
        new: Convention to convert to, restricted to ``joint_names`` in that order.
        columns: Index in the feature vector of each converted joint; ``None``: every entry is converted
            (then ``joint_names`` is the whole vector).
        width: Entries per frame ``D`` of the feature; ``None``: ``len(joint_names)``.
        passthrough: Names of the entries copied bit for bit (not joint positions, e.g. ``"x.vel"``).
    """

    key: str
    joint_names: tuple[str, ...]
    old: ValueConvention
    new: ValueConvention
    columns: tuple[int, ...] | None = None
    width: int | None = None
    passthrough: tuple[str, ...] = ()

    @property
    def size(self) -> int:
        """Entries per frame ``D`` of the feature column."""
        return len(self.joint_names) if self.width is None else self.width

    @classmethod
    def build(
        cls, key: str, entry_names: Sequence[str], old: ValueConvention, new: ValueConvention
    ) -> FeaturePlan:
        """Match the feature's entries to the calibrated motors and select ``old`` and ``new`` to them.

        Entries that are joint positions (``"<motor>.pos"`` or a bare motor name, LeRobot's convention) are
        converted; every other entry (``"x.vel"``, ``"theta.vel"``, ...) is passed through unchanged.
        Calibrated motors that the feature does not hold are ignored.

        Args:
            key: Feature key.
            entry_names: The feature's entry names in column order (``"shoulder_pan.pos"`` or
                ``"shoulder_pan"``).
            old: The recording's convention (may hold more motors).
            new: The target convention (may hold more motors).

        Raises:
            JointMismatchError: A joint-position entry has no motor in a calibration (naming the entry), a
                joint appears twice, or the feature has no joint-position entry.
        """
        names = tuple(entry_names)
        columns = [i for i, e in enumerate(names) if is_position_entry(e)]
        joints = tuple(joint_name(names[i]) for i in columns)
        passthrough = tuple(e for e in names if not is_position_entry(e))
        if not joints:
            raise JointMismatchError(
                f"feature {key!r}: no joint-position entry ('<motor>.pos') to re-calibrate; "
                f"entries: {', '.join(names) or 'none'}"
            )
        dup = sorted({j for j in joints if joints.count(j) > 1})
        if dup:
            raise JointMismatchError(f"feature {key!r}: joint(s) {', '.join(dup)} appear twice")
        for conv, role in ((old, "old"), (new, "new")):
            available = set(conv.joint_names)
            missing = [names[i] for i, j in zip(columns, joints, strict=True) if j not in available]
            if missing:
                raise JointMismatchError(
                    f"feature {key!r}: joint-position entr{'y' if len(missing) == 1 else 'ies'} "
                    f"{', '.join(map(repr, missing))} not in the {role} calibration (its motors: "
                    f"{', '.join(conv.joint_names) or 'none'})"
                )
        o, n = old.select(joints), new.select(joints)
        check = getattr(o, "check_target", None)
        if callable(check):
            check(n)
        if len(joints) == len(names):
            return cls(key=key, joint_names=joints, old=o, new=n)
        return cls(
            key=key,
            joint_names=joints,
            old=o,
            new=n,
            columns=tuple(columns),
            width=len(names),
            passthrough=passthrough,
        )


def feature_convention(
    conv: Conventions, key: str, role: str
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
        ``(new_values (N, D), out_of_range (N, D))``; the mask marks positions outside ``new``'s range and,
        when ``old`` has an ``unrecordable(actual)`` method, positions ``old`` cannot have recorded (a
        Feetech value that does not come from one encoder turn).
    """
    v = np.asarray(values, dtype=np.float64)
    if v.ndim == 2 and v.shape[0] > _LUT_MIN_ROWS:
        uniq = _unique_columns(v)
        if uniq is not None:
            # recorded values come from whole ticks: map each distinct value of a column once
            table, idx = uniq
            table_values, table_mask = _map_actual(old.to_actual(table), old, new)
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
            grid_values, grid_mask = _map_actual(grid, old, new)
            idx = (actual - lo).astype(np.intp)
            return np.take_along_axis(grid_values, idx, axis=0), np.take_along_axis(grid_mask, idx, axis=0)
    return _map_actual(actual, old, new)


def _map_actual(
    actual: FloatArray, old: ValueConvention, new: ValueConvention
) -> tuple[FloatArray, BoolArray]:
    """``new.from_actual(actual)``, with positions ``old`` cannot have recorded added to the mask."""
    values, mask = new.from_actual(actual)
    unrecordable = getattr(old, "unrecordable", None)
    if callable(unrecordable):
        mask = mask | np.asarray(unrecordable(actual), dtype=np.bool_)
    return values, mask


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


def _column_values(column: pa.ChunkedArray | pa.Array, key: str) -> tuple[NDArray[Any], pa.DataType]:
    """The column as a numpy ``(N, D)`` array in its stored dtype (no conversion, so entries keep their bits)."""
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
    values: NDArray[Any] = np.asarray(flat.to_numpy(zero_copy_only=False)).reshape(-1, d)
    return values, typ


def _check_finite(values: FloatArray, key: str, columns: Sequence[int]) -> None:
    """Refuse NaN or inf in the converted entries (``values`` holds them, ``columns`` their positions)."""
    finite = np.isfinite(values)
    if not finite.all():
        row, col = np.argwhere(~finite)[0]
        raise FileFormatError(
            f"column {key!r}: {int((~finite).sum())} NaN or inf entries (first at row {row}, entry "
            f"{columns[col]}); expected finite numbers"
        )


def recalibrate_table_with_counts(
    table: pa.Table, plans: Sequence[FeaturePlan]
) -> tuple[pa.Table, dict[str, NDArrayInt], dict[str, NDArray[Any]]]:
    """Re-calibrate the planned feature columns of one table.

    Args:
        table: Frames, with each planned feature a ``fixed_size_list<float>[D]`` column.
        plans: One :class:`FeaturePlan` per feature to convert.

    Returns:
        ``(table, out_of_range, new_values)``: the new table (same schema), per feature the count of values
        outside the new calibrated range per converted joint (shape ``(len(plan.joint_names),)``), and per
        feature the stored new values ``(N, D)`` in the column's dtype, passed-through entries included
        (for statistics).

    Raises:
        FileFormatError: A column is missing, not a fixed-size list, has nulls, or NaN/inf in a converted
            entry (NaN in a passed-through entry is kept).
        ShapeMismatchError: A column's width differs from the feature's number of entries.
    """
    counts: dict[str, NDArrayInt] = {}
    stored: dict[str, NDArray[Any]] = {}
    out = table
    for plan in plans:
        idx = table.schema.get_field_index(plan.key)
        if idx < 0:
            raise FileFormatError(f"column {plan.key!r} is missing from the data table")
        raw, typ = _column_values(table.column(idx), plan.key)
        if raw.shape[1] != plan.size:
            entries = plan.joint_names if plan.columns is None else (*plan.joint_names, *plan.passthrough)
            raise ShapeMismatchError(
                f"column {plan.key!r} has {raw.shape[1]} entries per frame; "
                f"expected {plan.size} ({', '.join(entries)})"
            )
        columns = list(range(plan.size)) if plan.columns is None else list(plan.columns)
        values = np.asarray(raw if plan.columns is None else raw[:, columns], dtype=np.float64)
        _check_finite(values, plan.key, columns)
        new_values, mask = recalibrate_values(values, plan.old, plan.new)
        if plan.columns is None:
            cast = np.ascontiguousarray(new_values, dtype=raw.dtype)
        else:
            cast = np.array(raw, copy=True, order="C")  # passed-through entries keep their exact bits
            cast[:, columns] = new_values.astype(raw.dtype)
        child = pa.array(cast.reshape(-1), type=typ.value_type)
        new_col = pa.FixedSizeListArray.from_arrays(child, type=typ)
        out = out.set_column(idx, table.schema.field(idx), new_col)
        counts[plan.key] = mask.sum(axis=0).astype(np.int64)
        stored[plan.key] = cast
    return out, counts, stored


def recalibrate_table(
    table: pa.Table,
    old: Conventions,
    new: Conventions,
    *,
    features: Mapping[str, Sequence[str]] | None = None,
) -> pa.Table:
    """Re-calibrate the joint-position features of a table of frames.

    Args:
        table: Frames (e.g. one row group of a LeRobot data file).
        old: The recording's convention, one for all features or one per feature key.
        new: The target convention, one for all features or one per feature key.
        features: Feature key → entry names in column order, as in ``info.json`` (``"<motor>.pos"`` or a
            bare motor name; other entries such as ``"x.vel"`` are copied bit for bit). Default: every key
            of ``old`` when it is a mapping, else ``observation.state`` and ``action`` (those present), with
            ``old.joint_names``.

    Returns:
        A table with the same schema and the converted feature columns.

    Raises:
        UsageError: ``table`` is not a table, a calibration is not a convention or lacks a feature, or no
            feature is given and neither default column exists.
        JointMismatchError: A joint-position entry has no motor in a calibration (extra calibrated motors
            are fine).
        FileFormatError: A feature column is missing, not a ``fixed_size_list<float>`` or holds NaN in a
            converted entry.
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
