"""Many datasets' calibration health through datatrove (the executor ``robocal.dataset.cluster`` uses).

Each datatrove task (rank) checks the roots ``roots[rank::world_size]`` and writes ``OUT/<root name>.health.json``
(the report of ``robocal dataset health``, without the picture); a root the check refuses gets
``{"error": "..."}`` instead, so one bad dataset does not stop the others. Locally::

    paths = health_with_datatrove(roots, out, robot="so101_follower", tasks=2, workers=2)

On a Slurm cluster: ``SlurmPipelineExecutor(pipeline=[HealthDatasets(roots, out, template)], tasks=64, ...)``.
Needs the ``cluster`` extra (``pip install 'robocal[cluster]'``, datatrove).
"""

from __future__ import annotations

import json
from collections.abc import Sequence
from dataclasses import replace
from pathlib import Path
from typing import Any

from ...errors import BackendNotAvailableError, CalibError, UsageError
from .health import HealthRequest, evaluate_health

try:
    from datatrove.pipeline.base import PipelineStep
except ImportError:  # pragma: no cover - exercised only without the extra
    raise BackendNotAvailableError(
        "checking many datasets with datatrove needs the Python package 'datatrove': pip install 'robocal[cluster]'"
    ) from None

__all__ = ["HealthDatasets", "health_with_datatrove", "report_path_for"]


def report_path_for(out: Path, root: Path) -> Path:
    """Where the report of ``root`` goes."""
    return out / f"{root.name}.health.json"


class HealthDatasets(PipelineStep):  # type: ignore[misc]
    """datatrove step: the calibration health of this rank's share of the dataset roots."""

    name = "robocal dataset health"
    type = "🤖 - CALIBRATION"

    def __init__(self, roots: Sequence[Path], out: Path, template: HealthRequest) -> None:
        super().__init__()
        self.roots = tuple(Path(r) for r in roots)
        self.out = Path(out)
        self.template = template

    def run(self, data: Any = None, rank: int = 0, world_size: int = 1) -> Any:
        """Check ``roots[rank::world_size]``; yields nothing (reports go to ``out``)."""
        for root in self.roots[rank::world_size]:
            try:
                _, report = evaluate_health(replace(self.template, root=root))
            except CalibError as exc:
                report = {"dataset": str(root), "error": str(exc)}
            path = report_path_for(self.out, root)
            part = path.with_suffix(".part")
            part.write_text(json.dumps(report, indent=2) + "\n")
            part.replace(path)
            self.stat_update("datasets")
        if data:
            yield from data


def health_with_datatrove(
    roots: Sequence[Path],
    out: Path,
    *,
    robot: str | None = None,
    use_degrees: bool | None = None,
    tasks: int = 1,
    workers: int = 1,
) -> list[Path]:
    """Check every root with datatrove's ``LocalPipelineExecutor``; return the report paths (``roots`` order).

    Raises:
        UsageError: ``tasks`` or ``workers`` below 1, or ``out`` is not a folder that can be made.
    """
    from datatrove.executor import LocalPipelineExecutor

    if tasks < 1 or workers < 1:
        raise UsageError(f"tasks {tasks}, workers {workers}: expected positive numbers")
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    template = HealthRequest(root=Path("."), report=out / "unused.json", robot=robot, use_degrees=use_degrees)
    LocalPipelineExecutor(
        pipeline=[HealthDatasets(roots, out, template)],
        tasks=tasks,
        workers=workers,
        logging_dir=str(out / "logs"),
        skip_completed=False,
    ).run()
    return [report_path_for(out, Path(r)) for r in roots]
