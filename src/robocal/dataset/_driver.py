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
from concurrent.futures import Future, ProcessPoolExecutor, as_completed
from concurrent.futures.process import BrokenProcessPool
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq

from ..errors import CalibError, FileFormatError, FileWriteError, UsageError
from ._convention import ValueConvention
from ._engine import FeaturePlan, FileResult, feature_convention, recalibrate_file
from ._layout import DatasetLayout, read_layout
from ._stats import StatAccumulator, is_known_stat, merge_all, merge_into

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


class DatasetWorkerError(CalibError, RuntimeError):
    """A worker process of the pool died (killed, out of memory); nothing was written. Exit code 3."""

    exit_code = 3


@dataclass
class DatasetReport:
    """Outcome of a dataset re-calibration.

    Attributes:
        src: Source root.
        dst: Destination root.
        features: Converted feature keys.
        joint_names: Per feature, the converted joints in column order (entries that are not joint
            positions, e.g. ``x.vel``, are passed through and not listed).
        frames: Total frames converted.
        files: Number of data files.
        row_groups: Number of row groups written.
        out_of_range: Per feature, per converted joint, count of values outside the new calibrated range
            or that cannot come from one encoder turn (Feetech).
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
        UsageError: A feature is unknown or not a named float vector, or a per-feature mapping lacks it.
        JointMismatchError: A joint-position entry (``"<motor>.pos"``) has no motor in a calibration.
    """
    return [
        FeaturePlan.build(
            feat.key,
            feat.names,
            feature_convention(old, feat.key, "old"),
            feature_convention(new, feat.key, "new"),
        )
        for feat in layout.select(features)
    ]


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
    if dst.is_symlink() and not dst.exists():
        raise UsageError(f"destination {dst} is a broken symbolic link; remove it or choose another folder")
    if not dst.parent.is_dir():
        raise UsageError(f"destination {dst}: parent folder {dst.parent} does not exist")


def check_metadata(layout: DatasetLayout) -> None:
    """Check ``meta/stats.json`` and the episode files can be rewritten, before anything is written.

    Raises:
        FileFormatError: Naming the file.
    """
    stats = layout.root / "meta" / "stats.json"
    if stats.is_file():
        _read_stats(stats)
    for rel in layout.episode_files:
        try:
            names = pq.read_schema(layout.root / rel).names
        except (pa.ArrowException, OSError) as exc:
            raise FileFormatError(f"episodes file {rel}: cannot read Parquet ({exc})") from None
        if "episode_index" not in names:
            raise FileFormatError(f"episodes file {rel}: no 'episode_index' column")


def _read_stats(path: Path) -> dict[str, Any]:
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise FileFormatError(f"{path}: cannot read statistics JSON ({exc})") from None
    except RecursionError:
        raise FileFormatError(f"{path}: statistics JSON nested too deeply") from None
    except ValueError as exc:  # e.g. an integer of more digits than Python converts
        raise FileFormatError(f"{path}: cannot read statistics JSON ({exc})") from None
    if not isinstance(data, dict):
        raise FileFormatError(f"{path}: expected a JSON object of features")
    return data


def _carry(src: Path, dst: Path, link: bool) -> None:
    """Hard-link (``link``, copy where the file system cannot) or copy the file ``src`` is or points to."""
    real = Path(os.path.realpath(src))  # a relative symbolic link would break in another folder
    dst.parent.mkdir(parents=True, exist_ok=True)
    if link:
        try:
            os.link(real, dst)
            return
        except OSError:
            pass
    shutil.copy2(real, dst)


def _work(args: tuple[str, str, str, list[FeaturePlan]]) -> FileResult:
    src, dst, rel, plans = args
    return recalibrate_file(src, dst, plans, rel)


def rewrite_episode_stats(
    src: Path,
    dst: Path,
    episode_stats: Mapping[int, Mapping[str, StatAccumulator]],
    features: Sequence[str],
    rel: str = "",
    *,
    keep_missing: bool = False,
) -> list[str]:
    """Copy an episodes metadata file, replacing ``stats/<feature>/<stat>`` columns of ``features``.

    Row groups, schema and metadata are kept; statistics robocal cannot compute are left out of the
    replacement and reported.

    Args:
        src: Source episodes file.
        dst: Destination file.
        episode_stats: Episode → feature → statistics of the new values.
        features: Converted feature keys.
        rel: Path used in messages.
        keep_missing: An episode without statistics keeps its source values (reported) instead of being an
            error; used when some data files have no ``episode_index`` column.

    Returns:
        Warnings (statistics kept from the source because they cannot be recomputed).
    """
    name = rel or str(src)
    warnings: list[str] = []
    kept: set[int] = set()
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
                    source = table.column(i).to_pylist() if keep_missing else []
                    for row, e in enumerate(eps):
                        acc = episode_stats.get(e, {}).get(key)
                        if acc is None:
                            if not keep_missing:
                                raise FileFormatError(
                                    f"episodes file {name}: episode {e} has no frames in data/"
                                )
                            kept.add(e)
                            values.append(source[row])
                            continue
                        values.append(acc.get(stat))
                    field_ = table.schema.field(i)
                    table = table.set_column(i, field_, pa.array(values, type=field_.type))
                writer.write_table(table, row_group_size=max(table.num_rows, 1))
    except (pa.ArrowException, OSError) as exc:
        raise FileFormatError(f"episodes file {name}: cannot read or write Parquet ({exc})") from None
    if kept:
        listed = ", ".join(str(e) for e in sorted(kept)[:10]) + (", ..." if len(kept) > 10 else "")
        warnings.append(
            f"{name}: per-episode statistics of {', '.join(features)} for {len(kept)} episode(s) "
            f"({listed}) could not be updated (their frames are in data files without 'episode_index'); "
            "they still describe the old calibration"
        )
    return warnings


def write_dataset_stats(
    src: Path, dst: Path, totals: Mapping[str, StatAccumulator], features: Sequence[str]
) -> list[str]:
    """Write ``meta/stats.json`` with the statistics of ``features`` recomputed; others copied as they are.

    Returns:
        Warnings (statistics kept from the source because they cannot be recomputed).
    """
    warnings: list[str] = []
    stats = _read_stats(src)
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
    if isinstance(workers, bool) or not isinstance(workers, int) or workers < 1:
        raise UsageError(f"--workers {workers}: expected a positive number of processes")
    layout = read_layout(src_p)
    plans = build_plans(layout, old, new, features)
    check_destination(src_p, dst_p, overwrite)
    check_metadata(layout)
    keys = tuple(p.key for p in plans)
    report = DatasetReport(
        src=src_p, dst=dst_p, features=keys, joint_names={p.key: p.joint_names for p in plans}
    )
    tmp = make_temp_root(dst_p)
    try:
        _build(layout, tmp, plans, workers, report, on_file_done)
        publish_root(tmp, dst_p)
    except BaseException as exc:
        shutil.rmtree(tmp, ignore_errors=True)
        if isinstance(exc, OSError) and not isinstance(exc, CalibError):  # a full disk, a read-only folder
            where = f" ({exc.filename})" if exc.filename else ""
            raise FileWriteError(
                f"cannot write {dst_p}: {exc.strerror or exc}{where}; nothing written"
            ) from None
        raise
    return report


def _source_files(root: Path) -> list[tuple[str, Path]]:
    """Every file under ``root`` as (relative POSIX path, path), following symbolic links to folders.

    Raises:
        FileFormatError: A broken symbolic link (naming it).
    """
    out: list[tuple[str, Path]] = []
    seen: set[str] = set()
    for dirpath, dirnames, filenames in os.walk(root, followlinks=True):
        real = os.path.realpath(dirpath)
        if real in seen:  # a link loop
            dirnames.clear()
            continue
        seen.add(real)
        for name in filenames:
            path = Path(dirpath) / name
            rel = path.relative_to(root).as_posix()
            if not path.exists():
                raise FileFormatError(f"dataset {root}: {rel} is a broken symbolic link")
            out.append((rel, path))
    return sorted(out)


def prepare_root(layout: DatasetLayout, tmp: Path) -> None:
    """Carry every file that is not re-calibrated into ``tmp`` (videos linked) and create the data folders.

    Symbolic links (to files or folders) are followed: the new root holds the files themselves.

    Raises:
        FileFormatError: A broken symbolic link or a file that cannot be read or written.
    """
    root = layout.root
    special = set(layout.data_files) | set(layout.episode_files) | {"meta/stats.json"}
    try:
        for rel, path in _source_files(root):
            if rel not in special:
                _carry(path, tmp / rel, link=rel.startswith("videos/") or path.suffix in _VIDEO_SUFFIXES)
        for rel in layout.data_files:
            (tmp / rel).parent.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise FileFormatError(f"dataset {root}: cannot copy {exc.filename or ''} ({exc.strerror})") from None


_VIDEO_SUFFIXES = (".mp4", ".mkv", ".avi")


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
    if workers == 1 or len(jobs) <= 1:
        for job in jobs:
            res = _work(job)
            results.append(res)
            if on_file_done is not None:
                on_file_done(res.path, res.frames)
    else:
        with ProcessPoolExecutor(max_workers=min(workers, len(jobs))) as pool:
            futures: list[Future[FileResult]] = [pool.submit(_work, job) for job in jobs]
            try:
                for fut in as_completed(futures):
                    try:
                        res = fut.result()  # a worker's exception is raised here
                    except BrokenProcessPool:
                        raise DatasetWorkerError(
                            f"a worker process died while converting {root} (out of memory or killed); "
                            "nothing was written — retry with fewer --workers"
                        ) from None
                    if on_file_done is not None:
                        on_file_done(res.path, res.frames)
            except BaseException:
                # an error or Ctrl-C: drop the queued files, wait only for the ones being written
                pool.shutdown(wait=True, cancel_futures=True)
                raise
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
    unindexed: list[FileResult] = []
    for res in results:
        report.frames += res.frames
        report.files += 1
        report.row_groups += res.row_groups
        merge_into(episode_acc, res.episode_stats)
        if not res.has_episode_index:
            unindexed.append(res)
            report.warnings.append(
                f"data file {res.path} has no 'episode_index' column: meta/stats.json is recomputed from "
                f"its {res.frames} frames, but per-episode statistics cannot be updated for them"
            )
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
        report.warnings += rewrite_episode_stats(
            root / rel, tmp / rel, episode_acc, keys, rel, keep_missing=bool(unindexed)
        )
    stats_src = root / "meta" / "stats.json"
    if stats_src.is_file():
        totals: dict[str, StatAccumulator] = {}
        for key in keys:
            parts = [accs[key] for accs in episode_acc.values() if key in accs]
            parts += [res.file_stats[key] for res in unindexed if key in res.file_stats]
            t = merge_all(parts)
            if t is not None:
                totals[key] = t
        report.warnings += write_dataset_stats(stats_src, tmp / "meta" / "stats.json", totals, keys)
    with contextlib.suppress(OSError):
        shutil.copystat(root, tmp)


def make_temp_root(dst: Path, kind: str = "robocal") -> Path:
    """Create an empty temporary folder beside ``dst`` (same file system, so the final rename is atomic)."""
    final = Path(os.path.abspath(dst))  # "." or "out/.." have no usable name or parent otherwise
    prefix = f".{final.name}.{kind}-"
    if len(os.fsencode(prefix)) + 8 > 255:  # a long DST name: a short temporary name still fits
        prefix = f".rc-{kind}-"
    try:
        return Path(tempfile.mkdtemp(prefix=prefix, dir=final.parent))
    except OSError as exc:
        raise FileWriteError(
            f"cannot write {dst}: cannot create a folder in {final.parent} ({exc.strerror or exc}); nothing written"
        ) from None
    except UnicodeError:
        raise FileWriteError(
            f"cannot write {str(dst)!a}: the name is not valid Unicode (a lone surrogate)"
        ) from None


def publish_root(tmp: Path, dst: Path) -> None:
    """Rename the finished ``tmp`` root to ``dst``, replacing an existing ``dst`` only now.

    Raises:
        FileFormatError: The rename failed; an existing ``dst`` is put back.
    """
    final = Path(os.path.abspath(dst))
    try:
        if not final.exists():
            os.replace(tmp, final)
            return
        old_dir = make_temp_root(final, "old")
        os.replace(final, old_dir / "root")
        try:
            os.replace(tmp, final)
        except OSError:
            os.replace(old_dir / "root", final)
            os.rmdir(old_dir)
            raise
        shutil.rmtree(old_dir, ignore_errors=True)
    except OSError as exc:
        raise FileFormatError(
            f"destination {dst}: cannot move the new dataset into place ({exc.strerror})"
        ) from None
