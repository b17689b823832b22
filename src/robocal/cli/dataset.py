"""``robocal dataset`` commands: re-calibrate and inspect recorded LeRobot v3 datasets."""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING, Annotated

import typer
from rich.console import Console
from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeElapsedColumn
from rich.table import Table

from . import _common
from ._options import LeRobotArm, LeRobotCompat, LeRobotModes, LeRobotPhysical, LeRobotUseDegrees

if TYPE_CHECKING:
    from ..workflows.dataset.job import DatasetOptions

app = typer.Typer(help="Re-calibrate, inspect and health-check recorded LeRobot v3 datasets.", no_args_is_help=True)


def _options(
    robot: str | None,
    motor_family: str | None,
    use_degrees: bool | None,
    modes: str | None,
    old_modes: str | None,
    compat: str,
    physical: bool = False,
) -> DatasetOptions:
    from ..workflows.dataset.job import DatasetOptions

    return DatasetOptions(
        robot=robot,
        motor_family=motor_family,
        use_degrees=use_degrees,
        modes=_common.parse_assignments(modes, "--modes") or None,
        old_modes=_common.parse_assignments(old_modes, "--old-modes") or None,
        compat=compat,
        convention="physical" if physical else "lerobot",
    )


Family = Annotated[
    str | None, typer.Option("--motor-family", help="feetech or dynamixel (default: --robot).")
]
Features = Annotated[
    str | None,
    typer.Option("--features", help="Comma-separated features (default observation.state,action)."),
]


@app.command()
def recalibrate(
    src: Annotated[Path, typer.Argument(help="Source dataset root (LeRobot v3).")],
    dst: Annotated[Path, typer.Argument(help="New dataset root (must not exist unless --overwrite).")],
    old: Annotated[Path, typer.Option("--old", help="Calibration the dataset was recorded with.")],
    new: Annotated[Path, typer.Option("--new", help="Calibration to convert to.")],
    features: Features = None,
    workers: Annotated[int, typer.Option("--workers", help="Worker processes.")] = 1,
    robot: LeRobotArm = None,
    motor_family: Family = None,
    use_degrees: LeRobotUseDegrees = None,
    modes: LeRobotModes = None,
    old_modes: Annotated[
        str | None, typer.Option("--old-modes", help="Modes of the old calibration if different.")
    ] = None,
    compat: LeRobotCompat = "lerobot",
    physical: LeRobotPhysical = False,
    overwrite: Annotated[
        bool, typer.Option("--overwrite", help="Replace DST once the new root is complete.")
    ] = False,
) -> None:
    """Re-calibrate the joint features of a dataset: value → actual encoder position → new value."""
    from ..workflows.dataset.job import RecalibrateRequest, data_file_count
    from ..workflows.dataset.job import recalibrate as run

    feats = _common.parse_csv_list(features, "--features")
    opts = _options(robot, motor_family, use_degrees, modes, old_modes, compat, physical)
    with Progress(
        TextColumn("{task.description}"),
        BarColumn(),
        MofNCompleteColumn(),
        TextColumn("{task.fields[frames]} frames"),
        TimeElapsedColumn(),
        console=_common.err_console,
        transient=True,
        disable=not _common.err_console.is_terminal,
    ) as progress:
        task = progress.add_task("re-calibrating", total=None, frames=0)
        done = {"files": 0, "frames": 0}

        def on_file_done(path: str, frames: int) -> None:
            done["files"] += 1
            done["frames"] += frames
            progress.update(task, completed=done["files"], frames=done["frames"])

        progress.update(task, total=data_file_count(src))
        report = run(
            RecalibrateRequest(
                src, dst, old, new, features=feats, workers=workers, overwrite=overwrite, options=opts
            ),
            on_file_done=on_file_done,
        )
    for note in report.notes:
        _common.console.print(note, markup=False)
    _common.console.print(
        f"wrote {report.dst}: {report.frames} frames in {report.files} files, "
        f"{report.row_groups} row groups; features {', '.join(report.features)}"
    )
    raise typer.Exit(_common.print_warnings(report.warnings))


@app.command()
def inspect(
    root: Annotated[Path, typer.Argument(help="Dataset root (LeRobot v3).")],
    calibration: Annotated[
        Path | None, typer.Option("--calibration", help="The dataset's calibration file.")
    ] = None,
    features: Features = None,
    robot: LeRobotArm = None,
    motor_family: Family = None,
    use_degrees: LeRobotUseDegrees = None,
    modes: LeRobotModes = None,
    compat: LeRobotCompat = "lerobot",
    physical: LeRobotPhysical = False,
) -> None:
    """Per-joint min/max/mean; flags full-turn jumps and values outside the calibrated range (exit 1)."""
    from ..workflows.dataset.job import inspect as run

    opts = _options(robot, motor_family, use_degrees, modes, None, compat, physical)
    report = run(
        root, calibration=calibration, features=_common.parse_csv_list(features, "--features"), options=opts
    )
    table = Table(title=f"{report.root}: {report.frames} frames")
    for col in ("feature", "joint", "min", "max", "mean", "range", "jumps", "out of range", "NaN/inf"):
        table.add_column(col, justify="right" if col not in ("feature", "joint") else "left")
    for j in report.joints:
        rng = "-" if j.range_lo is None or j.range_hi is None else f"{j.range_lo:.3f}..{j.range_hi:.3f}"
        table.add_row(
            j.feature,
            j.joint,
            f"{j.min:.3f}",
            f"{j.max:.3f}",
            f"{j.mean:.3f}",
            rng,
            str(j.jumps),
            str(j.out_of_range),
            str(j.non_finite),
        )
    out = _common.console if _common.console.is_terminal else Console(highlight=False, width=160)
    out.print(table)
    for j in report.flagged:
        parts = []
        if j.jumps:
            parts.append(f"{j.jumps} full-turn jump(s) between frames")
        if j.out_of_range:
            parts.append(f"{j.out_of_range} value(s) outside the calibrated range")
        if j.non_finite:
            parts.append(f"{j.non_finite} NaN or infinite value(s)")
        _common.print_warning(f"{j.feature} {j.joint}: {'; '.join(parts)} — check the calibration")
    raise typer.Exit(_common.exit_code_for(report.flagged))


@app.command()
def health(
    root: Annotated[Path, typer.Argument(help="Teleoperation dataset root (LeRobot v3).")],
    report: Annotated[
        Path, typer.Option("--report", help="JSON report to write; the picture goes beside it (.png).")
    ],
    robot: LeRobotArm = None,
    urdf: Annotated[
        Path | None,
        typer.Option("--urdf", help="URDF with link masses for the sag model (default: the robot's shipped one)."),
    ] = None,
    leader_calibration: Annotated[
        Path | None, typer.Option("--leader-calibration", help="The leader's calibration file (action).")
    ] = None,
    follower_calibration: Annotated[
        Path | None,
        typer.Option("--follower-calibration", help="The follower's calibration file (observation.state)."),
    ] = None,
    use_degrees: LeRobotUseDegrees = None,
) -> None:
    """Find the joint whose leader/follower calibrations disagree (exit 1 when a joint is flagged)."""
    from ..workflows.dataset.health import HealthRequest, run_health

    outcome = run_health(
        HealthRequest(
            root=root,
            report=report,
            robot=robot,
            urdf=urdf,
            leader_calibration=leader_calibration,
            follower_calibration=follower_calibration,
            use_degrees=use_degrees,
        )
    )
    res = outcome.result
    table = Table(title=f"{res.root}: {res.frames} frames, {res.episodes} episodes (offset = follower − leader)")
    for col in ("joint", "status", "offset", "interval", "units", "range ends", "steps"):
        table.add_column(col, justify="right" if col in ("offset", "interval") else "left")
    for name, j in outcome.report["joints"].items():
        off, ci = (j["offset_deg"], j["ci_deg"]) if j["units"] == "degrees" else (j["offset"], j["ci"])
        unit = "°" if j["units"] == "degrees" else ""
        table.add_row(
            name,
            j["status"],
            "-" if off is None else f"{off:+.2f}{unit}",
            "-" if ci is None else f"[{ci[0]:+.2f}, {ci[1]:+.2f}]{unit}",
            j["units"],
            ", ".join(f"{e['end']} {e['kind']}" for e in j["range_ends"]) or "none",
            ", ".join(f"ep {s['episode']} fr {s['frame']}" for s in j["jumps"]) or "-",
        )
    out = _common.console if _common.console.is_terminal else Console(highlight=False, width=160)
    out.print(table)
    if urdf is not None and outcome.report["model"]["urdf"] is None:  # said, not only in the report
        _common.print_warning(f"--urdf {urdf}: no link masses; the sag was fitted from the data instead")
    flagged = [(n, j) for n, j in outcome.report["joints"].items() if j["status"] in ("offset", "suspect")]
    for name, j in flagged:
        _common.print_warning(f"{name}: {j['status']}: {'; '.join(j['reasons']) or 'offset past the threshold'}")
    _common.console.print(f"wrote {outcome.report_path} and {outcome.picture_path}", markup=False)
    raise typer.Exit(_common.exit_code_for(flagged))
