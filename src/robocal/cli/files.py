"""``robocal convert`` and ``robocal check``: calibration files between formats and against a URDF."""

from __future__ import annotations

from pathlib import Path

import typer
from rich.markup import escape
from rich.table import Table

from ._catalog import FORMAT_NAMES
from ._common import (
    EXIT_OK,
    EXIT_WARNINGS,
    PLAIN_TABLE_ROWS,
    console,
    exit_code_for,
    parse_csv_list,
    print_plain_table,
    print_warning,
)
from ._options import DEFAULT_TOPIC, ReplayFrame, ReplayTopic, RobotProfile

FORMAT_HELP = "Format: " + ", ".join(FORMAT_NAMES) + "."


def convert(
    src: Path = typer.Argument(..., help="Calibration file to read."),
    dst: Path = typer.Argument(
        ..., help="File to write (updated in place when it exists and the format allows)."
    ),
    from_fmt: str | None = typer.Option(
        None, "--from", help="Source format (detected when omitted). " + FORMAT_HELP
    ),
    to_fmt: str | None = typer.Option(
        None, "--to", help="Destination format (from DST when omitted). " + FORMAT_HELP
    ),
    urdf: Path | None = typer.Option(None, "--urdf", help="URDF giving directions, ids and joint order."),
    joints: str | None = typer.Option(
        None, "--joints", help="Comma-separated joint order (positional formats)."
    ),
    robot: RobotProfile = None,
) -> None:
    """Convert a calibration file between formats, exactly."""
    from ..workflows.files.job import convert_file

    result = convert_file(
        src,
        dst,
        src_format=from_fmt,
        dst_format=to_fmt,
        urdf_path=urdf,
        joints=parse_csv_list(joints, "--joints"),
        robot=robot,
    )
    for note in result.notes:
        print_warning(note)
    console.print(
        f"wrote {dst} ({result.dst_format}) from {src} ({result.src_format}): {len(result.joints)} joints"
    )
    if result.robot:
        console.print(f"robot profile: {result.robot}", markup=False)
    raise typer.Exit(exit_code_for(result.notes))


def check(
    calibration: Path = typer.Option(..., "--calibration", help="Calibration file to check."),
    urdf: Path = typer.Option(..., "--urdf", help="The robot's URDF (expanded, not xacro)."),
    fmt: str | None = typer.Option(None, "--format", help="Calibration format (detected when omitted)."),
    source: str | None = typer.Option(
        None, "--source", help="Also read the robot once (sim:, can:, replay:)."
    ),
    topic: ReplayTopic = DEFAULT_TOPIC,
    frame: ReplayFrame = None,
    robot: RobotProfile = None,
) -> None:
    """Check a calibration file against a URDF: matched joints, ids, directions, offsets."""
    if source is not None:  # a malformed --source / --frame fails before anything is printed
        from ..workflows.sweep.power_on_check import check_source_options

        check_source_options(source, frame)
    from ..workflows.files.job import check_file

    checked = check_file(calibration, urdf, fmt, robot)
    report, profile = checked.report, checked.profile
    for note in checked.notes:
        print_warning(note)
    console.print(f"{calibration}: {len(report.matched)}/{report.n_expected} joints matched ({checked.fmt})")
    if profile is not None:
        how = "--robot" if robot is not None else "recognised from the URDF's joint names"
        console.print(f"robot profile: {profile.name} ({how})", markup=False)
    headers = ("joint", "id", "direction", "homing_offset", "status")
    rows = [
        (
            j.name,
            str(j.motor_id if j.motor_id is not None else "-"),
            f"{j.direction:+d}" if j.direction else "-",
            f"{j.homing_offset:.6f}" if j.homing_offset is not None else "-",
            "; ".join(j.warnings) if j.warnings else "ok",
        )
        for j in report.joints
    ]
    if len(rows) > PLAIN_TABLE_ROWS:
        print_plain_table(headers, rows)
    else:
        table = Table(*headers, box=None, pad_edge=False)
        for row in rows:
            table.add_row(
                *(escape(c) for c in row[:-1]),
                f"[{'green' if row[-1] == 'ok' else 'yellow'}]{escape(row[-1])}[/]",
            )
        console.print(table)
    if report.missing:
        print_warning(f"joints missing from the calibration file: {', '.join(report.missing)}")
    if report.extra:
        print_warning(report.extra_message)
    for j in report.joints:
        for w in j.warnings:
            print_warning(f"{j.name}: {w}")
    ok = report.ok and not checked.notes
    if (
        source is not None
    ):  # first reading after power-on, with the 2π branch selection (robocal.workflows.sweep.power_on_check)
        from ..workflows.sweep.power_on_check import check_source

        for c in check_source(urdf, calibration, source, topic=topic, frame=frame, robot=profile):
            turns = f" ({c.turns:+d} turn)" if c.turns else ""
            console.print(f"{c.name}: q = {c.q_rad:+.4f} rad{turns}", markup=False)
            if c.problem:
                print_warning(c.problem)
                ok = False
    raise typer.Exit(EXIT_OK if ok else EXIT_WARNINGS)


def register(app: typer.Typer) -> None:
    """Add ``convert`` and ``check`` to the root app."""
    app.command("convert")(convert)
    app.command("check")(check)
