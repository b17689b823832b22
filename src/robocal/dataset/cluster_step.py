"""The shape of robocal's datatrove jobs: each task (rank) takes its share of a list, writes one file per item.

:class:`ShareStep` is the pipeline step (``items[rank::world_size]``, one item at a time, counted), used by
:class:`robocal.dataset.cluster.RecalibrateFiles` (data files) and
:class:`robocal.workflows.dataset.health_cluster.HealthDatasets` (dataset roots); :func:`write_whole` leaves a
task's file whole or not at all; :func:`run_locally` runs one step with datatrove's ``LocalPipelineExecutor``.

Needs the ``cluster`` extra (``pip install 'robocal[cluster]'``, datatrove); the modules that use it raise the
missing-package error first, in their own words.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import Any

from datatrove.pipeline.base import PipelineStep

from ..errors import UsageError

__all__ = ["ShareStep", "check_parallelism", "run_locally", "write_whole"]


class ShareStep(PipelineStep):  # type: ignore[misc]
    """datatrove step: handle this rank's share ``items[rank::world_size]``, one :meth:`process` call each.

    Subclasses set ``name`` and :attr:`counter` (the datatrove statistic counted once per item) and
    implement :meth:`process`. The step yields nothing of its own; documents given to it pass through.
    """

    type = "🤖 - CALIBRATION"
    counter = "items"

    def __init__(self, items: Sequence[Any]) -> None:
        super().__init__()
        self.items = tuple(items)

    def process(self, item: Any) -> None:
        """Handle one item (write its file)."""
        raise NotImplementedError

    def run(self, data: Any = None, rank: int = 0, world_size: int = 1) -> Any:
        """Process ``items[rank::world_size]``; yields what ``data`` holds, nothing else."""
        for item in self.items[rank::world_size]:
            self.process(item)
            self.stat_update(self.counter)
        if data:
            yield from data


def write_whole(path: Path, data: bytes) -> None:
    """Write ``path`` beside it first (``.part``) and rename it into place: a reader sees all of it or nothing."""
    part = path.with_suffix(".part")
    part.write_bytes(data)
    part.replace(path)


def check_parallelism(tasks: int, workers: int) -> None:
    """Refuse task or worker counts below 1.

    Raises:
        UsageError: ``tasks`` or ``workers`` below 1.
    """
    if tasks < 1 or workers < 1:
        raise UsageError(f"tasks {tasks}, workers {workers}: expected positive numbers")


def run_locally(step: ShareStep, *, tasks: int, workers: int, logging_dir: Path) -> None:
    """Run ``step`` in ``tasks`` datatrove tasks on ``workers`` local processes (logs in ``logging_dir``)."""
    from datatrove.executor import LocalPipelineExecutor

    LocalPipelineExecutor(
        pipeline=[step], tasks=tasks, workers=workers, logging_dir=str(logging_dir), skip_completed=False
    ).run()
