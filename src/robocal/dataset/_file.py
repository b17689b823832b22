"""One Parquet data file re-calibrated row group by row group (one row group per episode stays one).

The output keeps the source's Arrow schema (with the ``huggingface`` metadata), row groups and compression;
the values go through :func:`._engine.recalibrate_table_with_counts`, and per-episode statistics of the new
values are accumulated on the way.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from concurrent.futures import Future, ThreadPoolExecutor
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq
from numpy.typing import NDArray

from ..errors import FileFormatError, InvalidCalibrationError
from ._engine import FeaturePlan, NDArrayInt, recalibrate_table_with_counts
from ._stats import StatAccumulator, episode_stats, merge_into
from .teleop_frames import episode_numbers

__all__ = ["FileResult", "recalibrate_file"]


@dataclass
class FileResult:
    """What re-calibrating one data file produced.

    Attributes:
        path: File path relative to the dataset root.
        frames: Number of frames (rows).
        row_groups: Number of row groups written (equal to the source's).
        out_of_range: Per feature, count per joint of values outside the new calibrated range, shape ``(D,)``.
        episode_stats: Episode index → feature → accumulated statistics of the new values.
        has_episode_index: Whether the file has an ``episode_index`` column. Without one,
            ``episode_stats`` stays empty and ``file_stats`` holds the statistics of its frames.
        file_stats: Feature → statistics of the new values of a file without ``episode_index`` (merged
            from one accumulator per row group, like LeRobot's ``aggregate_stats`` over episodes).
    """

    path: str
    frames: int = 0
    row_groups: int = 0
    out_of_range: dict[str, NDArrayInt] = field(default_factory=dict)
    episode_stats: dict[int, dict[str, StatAccumulator]] = field(default_factory=dict)
    has_episode_index: bool = True
    file_stats: dict[str, StatAccumulator] = field(default_factory=dict)


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


def _add_file_stats(
    dest: dict[str, StatAccumulator], stored: Mapping[str, NDArray[Any]], sizes: Sequence[int]
) -> None:
    """Merge the statistics of each row group (``sizes`` rows each, consecutive) of ``stored`` into ``dest``."""
    for key, values in stored.items():
        offset = 0
        for n in sizes:
            if n:
                acc = StatAccumulator.of(np.asarray(values[offset : offset + n], dtype=np.float64))
                dest[key] = dest[key].merge(acc) if key in dest else acc
            offset += n


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
        FileFormatError: The file cannot be read as Parquet or a column is malformed (an ``episode_index`` that
            is not an integer in every row, as ``dataset inspect`` and ``health`` refuse it).
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
    result.has_episode_index = has_episode
    if has_episode:  # its type, before anything is written (the rows' nulls are checked batch by batch)
        episode_numbers(schema.empty_table(), name)
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
                # the check dataset inspect and health make: an integer in every row (not a NaN cast, a float cut)
                episodes = episode_numbers(table, name) if has_episode else None
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
                if episodes is not None and new_table.num_rows:
                    merge_into(result.episode_stats, episode_stats(episodes, stored, keep_edges=True))
                    # an episode may continue in the next batch or file: keep the frames of the file's
                    # first and of the latest episode only (exact quantiles when the parts are joined)
                    edges = {int(episodes[-1]), next(iter(result.episode_stats))}
                    for ep, accs in result.episode_stats.items():
                        if ep not in edges:
                            for key, a in accs.items():
                                accs[key] = a.without_samples()
                elif new_table.num_rows:
                    # no episode_index: the dataset statistics are still recomputed from the frames
                    _add_file_stats(result.file_stats, stored, [sizes[g] for g in batch])
            if pending is not None:
                pending.result()
    except (pa.ArrowException, OSError) as exc:
        raise FileFormatError(f"data file {name}: cannot read or write Parquet ({exc})") from None
    return result
