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

from ...errors import BackendNotAvailableError, CalibError
from .health import HealthRequest, evaluate_health

try:
    import datatrove  # noqa: F401
except ImportError:  # pragma: no cover - exercised only without the extra
    raise BackendNotAvailableError(
        "checking many datasets with datatrove needs the Python package 'datatrove': pip install 'robocal[cluster]'"
    ) from None

from ...dataset.cluster_step import ShareStep, check_parallelism, run_locally, write_whole

__all__ = ["HealthDatasets", "health_with_datatrove", "report_path_for"]


def report_path_for(out: Path, root: Path) -> Path:
    """Where the report of ``root`` goes."""
    return out / f"{root.name}.health.json"


class HealthDatasets(ShareStep):
    """datatrove step: the calibration health of this rank's share of the dataset roots."""

    name = "robocal dataset health"
    counter = "datasets"

    def __init__(self, roots: Sequence[Path], out: Path, template: HealthRequest) -> None:
        super().__init__(tuple(Path(r) for r in roots))
        self.out = Path(out)
        self.template = template

    def process(self, item: Path) -> None:
        """Check one root; its report (or the refusal) goes to ``out``."""
        try:
            _, report = evaluate_health(replace(self.template, root=item))
        except CalibError as exc:
            report = {"dataset": str(item), "error": str(exc)}
        write_whole(report_path_for(self.out, item), (json.dumps(report, indent=2) + "\n").encode())


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
    check_parallelism(tasks, workers)
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    template = HealthRequest(root=Path("."), report=out / "unused.json", robot=robot, use_degrees=use_degrees)
    run_locally(HealthDatasets(roots, out, template), tasks=tasks, workers=workers, logging_dir=out / "logs")
    return [report_path_for(out, Path(r)) for r in roots]
