"""Cluster adapter: re-calibrate a dataset with a datatrove pipeline (LeRobot's engine for dataset porting).

Each datatrove task (rank) re-calibrates the data files ``data_files[rank::world_size]`` with the same
per-file engine as the local driver and leaves a small result file per data file; after all tasks finished,
:func:`finish` writes the statistics and renames the new root into place. Locally::

    report = recalibrate_with_datatrove(src, dst, old, new, tasks=4, workers=2)

On a Slurm cluster, build the job by hand and run the same three steps::

    job = prepare(src, dst, old, new)                       # validates, creates the temporary root
    SlurmPipelineExecutor(pipeline=[RecalibrateFiles(job)], tasks=64, ...).run()
    report = finish(job)                                    # stats, rename; run after every task ended

Needs the ``cluster`` extra (``pip install 'robocal[cluster]'``, datatrove).
"""

from __future__ import annotations

import pickle
import shutil
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

from ..errors import BackendNotAvailableError, FileFormatError
from ._convention import Conventions
from ._driver import DatasetReport, check_job, finish_root
from ._engine import FeaturePlan
from ._file import FileResult, recalibrate_file
from ._layout import read_layout
from ._root import make_temp_root, prepare_root, publish_root

try:
    import datatrove  # noqa: F401
except ImportError:  # pragma: no cover - exercised only without the extra
    raise BackendNotAvailableError(
        "the datatrove cluster adapter needs the Python package 'datatrove': pip install 'robocal[cluster]'"
    ) from None

from .cluster_step import ShareStep, check_parallelism, run_locally, write_whole

__all__ = ["ClusterJob", "RecalibrateFiles", "finish", "prepare", "recalibrate_with_datatrove"]


@dataclass(frozen=True)
class ClusterJob:
    """A prepared re-calibration: what every task needs, picklable.

    Attributes:
        src: Source root.
        dst: Final destination root.
        tmp: Temporary sibling root being built.
        work: Folder for per-file results (outside ``tmp``).
        data_files: Data files relative to ``src``.
        plans: Feature plans (conventions in column order).
    """

    src: Path
    dst: Path
    tmp: Path
    work: Path
    data_files: tuple[str, ...]
    plans: tuple[FeaturePlan, ...]


def prepare(
    src: str | Path,
    dst: str | Path,
    old: Conventions,
    new: Conventions,
    *,
    features: Sequence[str] | None = None,
    overwrite: bool = False,
) -> ClusterJob:
    """Validate everything and create the temporary root (videos and other files carried over).

    Raises:
        UsageError, JointMismatchError, FileFormatError: As :func:`robocal.dataset.recalibrate_dataset`.
    """
    src_p, dst_p, layout, plans = check_job(src, dst, old, new, features, overwrite)
    tmp = make_temp_root(dst_p)
    work = make_temp_root(dst_p, "robocal-work")
    try:
        prepare_root(layout, tmp)
    except BaseException:
        abort(ClusterJob(src_p, dst_p, tmp, work, layout.data_files, tuple(plans)))
        raise
    return ClusterJob(src_p, dst_p, tmp, work, layout.data_files, tuple(plans))


def _result_path(job: ClusterJob, rel: str) -> Path:
    return job.work / (rel.replace("/", "__") + ".result.pkl")


class RecalibrateFiles(ShareStep):
    """datatrove step: re-calibrate this rank's share of the data files of a :class:`ClusterJob`."""

    name = "robocal recalibrate"
    counter = "files"

    def __init__(self, job: ClusterJob) -> None:
        super().__init__(job.data_files)
        self.job = job

    def process(self, item: str) -> None:
        """Re-calibrate one data file; its result goes to ``job.work``."""
        res = recalibrate_file(self.job.src / item, self.job.tmp / item, self.job.plans, item)
        write_whole(_result_path(self.job, item), pickle.dumps(res))
        self.stat_update("frames", value=res.frames)


def finish(job: ClusterJob) -> DatasetReport:
    """Collect the per-file results, write statistics and rename the new root to ``job.dst``.

    Raises:
        FileFormatError: A data file has no result (a task failed or is still running); nothing is
            published and the temporary folders are removed.
    """
    try:
        results: list[FileResult] = []
        for rel in job.data_files:
            path = _result_path(job, rel)
            if not path.is_file():
                raise FileFormatError(f"data file {rel}: no result from the cluster run (a task failed?)")
            res = pickle.loads(path.read_bytes())
            if not isinstance(res, FileResult):
                raise FileFormatError(f"{path}: not a robocal result file")
            results.append(res)
        layout = read_layout(job.src)
        report = DatasetReport(
            src=job.src,
            dst=job.dst,
            features=tuple(p.key for p in job.plans),
            joint_names={p.key: p.joint_names for p in job.plans},
        )
        finish_root(layout, job.tmp, job.plans, results, report)
        publish_root(job.tmp, job.dst)
    except BaseException:
        abort(job)
        raise
    shutil.rmtree(job.work, ignore_errors=True)
    return report


def abort(job: ClusterJob) -> None:
    """Remove the temporary root and work folder of a job (``dst`` is left as it was)."""
    shutil.rmtree(job.tmp, ignore_errors=True)
    shutil.rmtree(job.work, ignore_errors=True)


def recalibrate_with_datatrove(
    src: str | Path,
    dst: str | Path,
    old: Conventions,
    new: Conventions,
    *,
    features: Sequence[str] | None = None,
    tasks: int = 1,
    workers: int = 1,
    overwrite: bool = False,
) -> DatasetReport:
    """Re-calibrate a dataset with datatrove's ``LocalPipelineExecutor``.

    Args:
        src: Source root.
        dst: Destination root.
        old: Convention the dataset was recorded with.
        new: Convention to convert to.
        features: Feature keys (default ``observation.state`` and ``action``).
        tasks: datatrove tasks (each takes every ``tasks``-th data file).
        workers: Parallel worker processes.
        overwrite: Replace an existing ``dst`` at the end.

    Returns:
        The same report as :func:`robocal.dataset.recalibrate_dataset`.
    """
    check_parallelism(tasks, workers)
    job = prepare(src, dst, old, new, features=features, overwrite=overwrite)
    try:
        run_locally(RecalibrateFiles(job), tasks=tasks, workers=workers, logging_dir=job.work / "logs")
    except BaseException:
        abort(job)
        raise
    return finish(job)
