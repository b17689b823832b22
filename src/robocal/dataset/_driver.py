"""Re-calibrate a whole LeRobot v3 dataset root into a new root.

Everything is validated before anything is written (features, joint names, destination, metadata). The new
root is built in a temporary sibling folder ``.DST.robocal-*`` (:mod:`._root`) and renamed to ``DST`` only when
every file is done, so a failure midway leaves no ``DST``. Data files (:mod:`._file`) are processed in a
:mod:`._pool` of worker processes (or in-process with one worker); the statistics metadata is
rewritten from their results (:mod:`._metadata`).
"""

from __future__ import annotations

import contextlib
import shutil
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..errors import CalibError, FileWriteError, UsageError
from ._convention import Conventions
from ._engine import FeaturePlan, feature_convention
from ._file import FileResult, recalibrate_file
from ._layout import DatasetLayout, read_layout
from ._metadata import check_metadata, rewrite_episode_stats, write_dataset_stats
from ._pool import WorkerDiedError, run_pool
from ._root import check_destination, make_temp_root, prepare_root, publish_root, sweep_leftovers
from ._stats import StatAccumulator, merge_all, merge_into

__all__ = [
    "DatasetReport",
    "DatasetWorkerError",
    "build_plans",
    "check_job",
    "finish_root",
    "recalibrate_dataset",
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
        warnings: Human-readable warnings (out-of-range joints, statistics not recomputed, temporary folders
            of other runs left beside ``dst``).
        notes: What was tidied up (temporary folders of killed runs removed).
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
    notes: list[str] = field(default_factory=list)


def build_plans(
    layout: DatasetLayout,
    old: Conventions,
    new: Conventions,
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


def check_job(
    src: str | Path,
    dst: str | Path,
    old: Conventions,
    new: Conventions,
    features: Sequence[str] | None,
    overwrite: bool,
) -> tuple[Path, Path, DatasetLayout, list[FeaturePlan]]:
    """Read and check all a re-calibration needs before anything is written.

    Returns:
        ``src`` and ``dst`` as paths, the source layout and the feature plans.

    Raises:
        UsageError, JointMismatchError, FileFormatError: As :func:`recalibrate_dataset`.
    """
    src_p, dst_p = Path(src), Path(dst)
    layout = read_layout(src_p)
    plans = build_plans(layout, old, new, features)
    check_destination(src_p, dst_p, overwrite)
    check_metadata(layout)
    return src_p, dst_p, layout, plans


def _work(args: tuple[str, str, str, list[FeaturePlan]]) -> FileResult:
    src, dst, rel, plans = args
    return recalibrate_file(src, dst, plans, rel)


def recalibrate_dataset(
    src: str | Path,
    dst: str | Path,
    old: Conventions,
    new: Conventions,
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
    if isinstance(workers, bool) or not isinstance(workers, int) or workers < 1:
        raise UsageError(f"--workers {workers}: expected a positive number of processes")
    src_p, dst_p, layout, plans = check_job(src, dst, old, new, features, overwrite)
    keys = tuple(p.key for p in plans)
    report = DatasetReport(
        src=src_p, dst=dst_p, features=keys, joint_names={p.key: p.joint_names for p in plans}
    )
    report.notes, report.warnings = sweep_leftovers(dst_p)
    tmp = make_temp_root(dst_p, owned=True)
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

        def done(res: FileResult) -> None:
            if on_file_done is not None:
                on_file_done(res.path, res.frames)

        try:
            # a worker's exception is raised here once the others are stopped; so is Ctrl-C
            results = run_pool(_work, jobs, workers, done, describe=lambda job: str(root / job[2]))
        except WorkerDiedError as exc:
            raise DatasetWorkerError(
                f"{exc}; nothing was written — if it ran out of memory, retry with fewer --workers"
            ) from None
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
