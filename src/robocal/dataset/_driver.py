"""Re-calibrate a whole LeRobot v3 dataset root into a new root.

Everything is validated before anything is written (features, joint names, destination). The new root
is built in a temporary sibling folder ``.DST.robocal-*`` and renamed to ``DST`` only when every file is
done, so a failure midway leaves no ``DST``. Data files are processed in a
:class:`~concurrent.futures.ProcessPoolExecutor` (or in-process with one worker); videos are hard-linked
(copied where linking fails), other files copied.
"""

from __future__ import annotations

import contextlib
import json
import os
import shutil
import tempfile
from collections.abc import Callable, Mapping, Sequence
from concurrent.futures import FIRST_EXCEPTION, Future, ProcessPoolExecutor, wait
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq

from ..errors import FileFormatError, UsageError
from ._convention import ValueConvention
from ._engine import FeaturePlan, FileResult, recalibrate_file
from ._layout import DatasetLayout, read_layout
from ._stats import StatAccumulator, is_known_stat, merge_all

__all__ = [
    "DatasetReport",
    "build_plans",
    "check_destination",
    "recalibrate_dataset",
    "rewrite_episode_stats",
    "write_dataset_stats",
]

ProgressCallback = Callable[[str, int], None]
"""Called after each data file with (relative path, frames in it)."""


@dataclass
class DatasetReport:
    """Outcome of a dataset re-calibration.

    Attributes:
        src: Source root.
        dst: Destination root.
        features: Converted feature keys.
        joint_names: Per feature, joint names in column order.
        frames: Total frames converted.
        files: Number of data files.
        row_groups: Number of row groups written.
        out_of_range: Per feature, per joint count of values outside the new calibrated range.
        warnings: Human-readable warnings (out-of-range joints, statistics not recomputed).
    """

    src: Path
    dst: Path
    features: tuple[str, ...]
    joint_names: dict[str, tuple[str, ...]]
    frames: int = 0
    files: int = 0
    row_groups: int = 0
    out_of_range: dict[str, dict[str, int]] = field(default_factory=dict)
    warnings: list[str] = field(default_factory=list)


def build_plans(
    layout: DatasetLayout,
    old: ValueConvention | Mapping[str, ValueConvention],
    new: ValueConvention | Mapping[str, ValueConvention],
    features: Sequence[str] | None = None,
) -> list[FeaturePlan]:
    """Resolve features and match their joint names against both calibrations.

    Raises:
        UsageError: A feature is unknown or not a named float vector.
        JointMismatchError: A feature's joints differ from a calibration's.
    """
    plans = []
    for feat in layout.select(features):
        o = old[feat.key] if isinstance(old, Mapping) else old
        n = new[feat.key] if isinstance(new, Mapping) else new
        plans.append(FeaturePlan.build(feat.key, feat.joint_names, o, n))
    return plans


def check_destination(src: Path, dst: Path, overwrite: bool) -> None:
    """Refuse a destination that exists (without ``overwrite``), overlaps the source or has no parent.

    Raises:
        UsageError: Naming the problem.
    """
    s, d = src.resolve(), dst.resolve()
    if s == d or s in d.parents or d in s.parents:
        raise UsageError(f"destination {dst} overlaps the source {src}; choose a separate folder")
    if dst.exists() and not overwrite:
        raise UsageError(f"destination {dst} already exists; pass --overwrite to replace it")
    if dst.exists() and not dst.is_dir():
        raise UsageError(f"destination {dst} exists and is not a folder")
    if not dst.parent.is_dir():
        raise UsageError(f"destination {dst}: parent folder {dst.parent} does not exist")


def check_metadata(layout: DatasetLayout) -> None:
    """Check ``meta/stats.json`` and the episode files can be rewritten, before anything is written.

    Raises:
        FileFormatError: Naming the file.
    """
    stats = layout.root / "meta" / "stats.json"
    if stats.is_file():
        try:
            data = json.loads(stats.read_text(encoding="utf-8"))
        except (OSError, UnicodeDecodeError, json.JSONDecodeError) as exc:
            raise FileFormatError(f"{stats}: cannot read statistics JSON ({exc})") from None
        if not isinstance(data, dict):
            raise FileFormatError(f"{stats}: expected a JSON object of features")
    for rel in layout.episode_files:
        try:
            names = pq.read_schema(layout.root / rel).names
        except (pa.ArrowException, OSError) as exc:
            raise FileFormatError(f"episodes file {rel}: cannot read Parquet ({exc})") from None
        if "episode_index" not in names:
            raise FileFormatError(f"episodes file {rel}: no 'episode_index' column")


def _link_or_copy(src: Path, dst: Path) -> None:
    dst.parent.mkdir(parents=True, exist_ok=True)
    try:
        os.link(src, dst)
    except OSError:
        shutil.copy2(src, dst)


def _work(args: tuple[str, str, str, list[FeaturePlan]]) -> FileResult:
    src, dst, rel, plans = args
    return recalibrate_file(src, dst, plans, rel)


def rewrite_episode_stats(
    src: Path,
    dst: Path,
    episode_stats: Mapping[int, Mapping[str, StatAccumulator]],
    features: Sequence[str],
    rel: str = "",
) -> list[str]:
    """Copy an episodes metadata file, replacing ``stats/<feature>/<stat>`` columns of ``features``.

    Row groups, schema and metadata are kept; statistics robocal cannot compute are left out of the
    replacement and reported.

    Returns:
        Warnings (statistics kept from the source because they cannot be recomputed).
    """
    name = rel or str(src)
    warnings: list[str] = []
    try:
        pf = pq.ParquetFile(src)
        schema = pf.schema_arrow
        with pq.ParquetWriter(dst, schema=schema) as writer:
            for g in range(pf.metadata.num_row_groups):
                table = pf.read_row_group(g)
                if "episode_index" not in table.schema.names:
                    raise FileFormatError(f"episodes file {name}: no 'episode_index' column")
                eps = [int(e) for e in table.column("episode_index").to_pylist()]
                for i, col_name in enumerate(table.schema.names):
                    parts = col_name.split("/")
                    if len(parts) != 3 or parts[0] != "stats" or parts[1] not in features:
                        continue
                    key, stat = parts[1], parts[2]
                    if not is_known_stat(stat):
                        warnings.append(f"{name}: statistic {col_name!r} cannot be recomputed; kept as is")
                        continue
                    values: list[Any] = []
                    for e in eps:
                        acc = episode_stats.get(e, {}).get(key)
                        if acc is None:
                            raise FileFormatError(f"episodes file {name}: episode {e} has no frames in data/")
                        values.append(acc.get(stat))
                    field_ = table.schema.field(i)
                    table = table.set_column(i, field_, pa.array(values, type=field_.type))
                writer.write_table(table, row_group_size=max(table.num_rows, 1))
    except (pa.ArrowException, OSError) as exc:
        raise FileFormatError(f"episodes file {name}: cannot read or write Parquet ({exc})") from None
    return warnings


def write_dataset_stats(
    src: Path, dst: Path, totals: Mapping[str, StatAccumulator], features: Sequence[str]
) -> list[str]:
    """Write ``meta/stats.json`` with the statistics of ``features`` recomputed; others copied as they are.

    Returns:
        Warnings (statistics kept from the source because they cannot be recomputed).
    """
    warnings: list[str] = []
    try:
        stats = json.loads(src.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise FileFormatError(f"{src}: cannot read statistics JSON ({exc})") from None
    if not isinstance(stats, dict):
        raise FileFormatError(f"{src}: expected a JSON object of features")
    for key in features:
        total = totals.get(key)
        if total is None:
            continue
        entry = stats.get(key)
        names = list(entry) if isinstance(entry, dict) else ["min", "max", "mean", "std", "count"]
        new_entry: dict[str, Any] = {}
        for stat in names:
            value = total.get(stat)
            if value is None:
                warnings.append(f"{src.name}: statistic {key}/{stat} cannot be recomputed; kept unchanged")
                assert isinstance(entry, dict)
                value = entry[stat]
            new_entry[stat] = value
        stats[key] = new_entry
    dst.write_text(json.dumps(stats, indent=4), encoding="utf-8")
    return warnings


def recalibrate_dataset(
    src: str | Path,
    dst: str | Path,
    old: ValueConvention | Mapping[str, ValueConvention],
    new: ValueConvention | Mapping[str, ValueConvention],
    *,
    features: Sequence[str] | None = None,
    workers: int = 1,
    overwrite: bool = False,
    on_file_done: ProgressCallback | None = None,
) -> DatasetReport:
    """Re-calibrate the joint features of a LeRobot v3 dataset into a new dataset root.

    Args:
        src: Source dataset root.
        dst: Destination root; must not exist unless ``overwrite``.
        old: Convention the dataset was recorded with (one, or one per feature key).
        new: Convention to convert to.
        features: Feature keys (default ``observation.state`` and ``action``, those present).
        workers: Worker processes for the data files (1 = in this process).
        overwrite: Replace an existing ``dst`` (only after the new root is complete).
        on_file_done: Progress callback after each data file.

    Returns:
        Frames, row groups, per-joint out-of-range counts and warnings.

    Raises:
        UsageError: Bad features, an existing or overlapping destination, ``workers < 1``.
        JointMismatchError: Feature joints differ from a calibration's.
        FileFormatError: A malformed dataset file (then no ``dst`` exists, or the old one is kept).
    """
    src_p, dst_p = Path(src), Path(dst)
    if workers < 1:
        raise UsageError(f"--workers {workers}: expected a positive number of processes")
    layout = read_layout(src_p)
    plans = build_plans(layout, old, new, features)
    check_destination(src_p, dst_p, overwrite)
    check_metadata(layout)
    keys = tuple(p.key for p in plans)
    report = DatasetReport(
        src=src_p, dst=dst_p, features=keys, joint_names={p.key: p.joint_names for p in plans}
    )
    tmp = Path(tempfile.mkdtemp(prefix=f".{dst_p.name}.robocal-", dir=dst_p.parent))
    try:
        _build(layout, tmp, plans, workers, report, on_file_done)
        publish_root(tmp, dst_p)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise
    return report


def prepare_root(layout: DatasetLayout, tmp: Path) -> None:
    """Carry every file that is not re-calibrated into ``tmp`` (videos linked) and create the data folders."""
    root = layout.root
    special = set(layout.data_files) | set(layout.episode_files) | {"meta/stats.json"}
    for path in sorted(root.rglob("*")):
        if path.is_dir():
            continue
        rel = path.relative_to(root).as_posix()
        if rel in special:
            continue
        if rel.startswith("videos/") or path.suffix in (".mp4", ".mkv", ".avi"):
            _link_or_copy(path, tmp / rel)
        else:
            (tmp / rel).parent.mkdir(parents=True, exist_ok=True)
            shutil.copy2(path, tmp / rel)
    for rel in layout.data_files:
        (tmp / rel).parent.mkdir(parents=True, exist_ok=True)


def _build(
    layout: DatasetLayout,
    tmp: Path,
    plans: list[FeaturePlan],
    workers: int,
    report: DatasetReport,
    on_file_done: ProgressCallback | None,
) -> None:
    root = layout.root
    prepare_root(layout, tmp)
    jobs = [(str(root / rel), str(tmp / rel), rel, plans) for rel in layout.data_files]
    results: list[FileResult] = []
    if workers == 1 or len(jobs) == 1:
        for job in jobs:
            res = _work(job)
            results.append(res)
            if on_file_done is not None:
                on_file_done(res.path, res.frames)
    else:
        with ProcessPoolExecutor(max_workers=min(workers, len(jobs))) as pool:
            futures: list[Future[FileResult]] = [pool.submit(_work, job) for job in jobs]
            pending: set[Future[FileResult]] = set(futures)
            while pending:
                done, pending = wait(pending, return_when=FIRST_EXCEPTION)
                for fut in done:
                    exc = fut.exception()
                    if exc is not None:
                        for other in pending:
                            other.cancel()
                        raise exc
                    res = fut.result()
                    if on_file_done is not None:
                        on_file_done(res.path, res.frames)
            results = [f.result() for f in futures]
    finish_root(layout, tmp, plans, results, report)


def finish_root(
    layout: DatasetLayout,
    tmp: Path,
    plans: Sequence[FeaturePlan],
    results: Sequence[FileResult],
    report: DatasetReport,
) -> None:
    """Fill ``report`` from the per-file results and write the episode and dataset statistics into ``tmp``."""
    root = layout.root
    keys = [p.key for p in plans]
    episode_acc: dict[int, dict[str, StatAccumulator]] = {}
    for res in results:
        report.frames += res.frames
        report.files += 1
        report.row_groups += res.row_groups
        for ep, accs in res.episode_stats.items():
            dest = episode_acc.setdefault(ep, {})
            for key, a in accs.items():
                dest[key] = dest[key].merge(a) if key in dest else a
    for plan in plans:
        total = np.zeros(len(plan.joint_names), dtype=np.int64)
        for res in results:
            total += res.out_of_range[plan.key]
        report.out_of_range[plan.key] = {n: int(c) for n, c in zip(plan.joint_names, total, strict=True)}
        bad = [f"{n} {c}" for n, c in report.out_of_range[plan.key].items() if c]
        if bad:
            report.warnings.append(
                f"{plan.key}: values outside the new calibrated range (clamped where the mode clamps): "
                + ", ".join(bad)
            )
    for rel in layout.episode_files:
        (tmp / rel).parent.mkdir(parents=True, exist_ok=True)
        report.warnings += rewrite_episode_stats(root / rel, tmp / rel, episode_acc, keys, rel)
    stats_src = root / "meta" / "stats.json"
    if stats_src.is_file():
        totals: dict[str, StatAccumulator] = {}
        for key in keys:
            t = merge_all(accs[key] for accs in episode_acc.values() if key in accs)
            if t is not None:
                totals[key] = t
        report.warnings += write_dataset_stats(stats_src, tmp / "meta" / "stats.json", totals, keys)
    with contextlib.suppress(OSError):
        shutil.copystat(root, tmp)


def publish_root(tmp: Path, dst: Path) -> None:
    """Rename the finished ``tmp`` root to ``dst``, replacing an existing ``dst`` only now."""
    if dst.exists():
        old_dir = Path(tempfile.mkdtemp(prefix=f".{dst.name}.old-", dir=dst.parent))
        os.replace(dst, old_dir / "root")
        os.replace(tmp, dst)
        shutil.rmtree(old_dir, ignore_errors=True)
    else:
        os.replace(tmp, dst)
