"""``robocal demo``: the main job end to end on a simulated robot (run by :mod:`robocal.workflows.demo.job`)."""

from __future__ import annotations

from pathlib import Path

import typer
from rich.table import Table

from ..errors import UsageError
from ..workflows.demo.job import (
    DEMO_ROBOTS,
    IDENTIFY_ROBOTS,
    LITE_DEMO_SOURCE,
    DemoResult,
    TruthTable,
    demo_folder,
    demo_urdf,
    prepare_demo,
    run_demo,
)
from . import _common


def truth_table(table: TruthTable) -> Table:
    """A rich table of a demo's truth table (name and status columns left, numbers right)."""
    t = Table(title=table.title)
    for i, col in enumerate(table.columns):
        t.add_column(col, justify="left" if i == 0 or col == "status" else "right")
    for row in table.rows:
        t.add_row(*row)
    return t


def render(result: DemoResult) -> int:
    """Print a demo's result (tables, the job's own output, lines, warnings); return the exit code."""
    con = _common.console
    if result.job == "auto":
        from ..workflows.autocal.model import AutoCalResult
        from ._autocal import auto_table

        auto = getattr(result.detail, "auto", None)  # AutoSweepOutcome (lite) or AutoCalibrationResult (arms)
        assert isinstance(auto, AutoCalResult)
        con.print(auto_table(auto))
    for section in result.sections:
        con.print(truth_table(section.table))
        for line in section.lines:
            con.print(line, markup=False)
    code = result.exit_code
    if result.job == "ur":
        from .ur import print_reports

        assert isinstance(result.detail, list)
        code = max(code, print_reports(result.detail))
    if result.job == "identify":
        from ..workflows.demo.identify import IdentifyDemo
        from ._kinematics_demo import print_identify_demo

        assert isinstance(result.detail, IdentifyDemo)
        code = max(code, print_identify_demo(result.detail))
    for line in result.lines:
        con.print(line, markup=False)
    for warning in result.warnings:
        _common.print_warning(warning)
    return code


def demo(
    robot: str = typer.Option("lite", "--robot", help="Simulated robot: " + ", ".join(DEMO_ROBOTS) + "."),
    out: Path | None = typer.Option(
        None, "--out", help="Folder for the files written (default: a temporary one)."
    ),
    identify: bool = typer.Option(
        False,
        "--identify",
        help=f"Kinematic identification instead ({', '.join(IDENTIFY_ROBOTS)}): simulate, identify, check.",
    ),
    view: bool = typer.Option(
        False,
        "--view",
        help="Then show the calibrated simulated Lite in the browser (robocal view; Ctrl-C to stop); with "
        "--auto, the stop search drawn on the robot as it runs.",
    ),
    port: int = typer.Option(8080, "--port", help="With --view: TCP port of the page (0: any free one)."),
    auto: bool = typer.Option(
        False, "--auto", help="The simulated joints find their own hard stops (lite, so101, koch, openarm; docs/auto_calibration.md)."
    ),
) -> None:
    """Calibrate a simulated robot end to end (default: the Lite humanoid's 14 Robstride joints)."""
    mode = "identify" if identify else None
    robot = prepare_demo(robot, out, mode)
    if auto:
        if identify:
            raise UsageError("--auto is its own demo; it does not go with --identify")
        from ._autocal import AutoLiveView, auto_demo_view

        if view:

            def run_auto(live: object) -> DemoResult:
                return run_demo(robot, out, mode="auto", say=_common.console.print, view=live)

            raise typer.Exit(auto_demo_view(run_auto, render, port, demo_urdf(robot)))
        result = run_demo(robot, out, mode="auto", say=_common.console.print, view=AutoLiveView())
        raise typer.Exit(render(result))
    if view:
        if robot != "lite" or identify:
            raise UsageError(
                "--view shows the Lite demo; for a LeRobot arm use "
                "`robocal view --urdf URDF --lerobot-port sim --robot so101_follower --calibration FILE`"
            )
        raise typer.Exit(_demo_view(out, port))
    result = run_demo(robot, out, mode=mode, say=_common.console.print)
    raise typer.Exit(render(result))


def _demo_view(out: Path | None, port: int) -> int:
    """Run the Lite sweep demo, then serve the calibrated simulated Lite; the worse of the two exit codes."""
    from ..viewer.app import check_port_free
    from ..viewer.demo import lite_view_options
    from . import view

    check_port_free("127.0.0.1", port)  # before the sweep, not after it
    with demo_folder(out, "sweep") as (folder, _temporary):
        code = render(run_demo("lite", folder, say=_common.console.print))
        if code not in (0, 1):
            return code
        opts = lite_view_options(folder / "calibration.yaml", LITE_DEMO_SOURCE, port=port)
        return max(code, view.serve(opts))


def register(app: typer.Typer) -> None:
    """Add ``demo`` to the root app."""
    app.command("demo")(demo)
