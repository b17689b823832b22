"""``robocal sweep``: hard-stop sweep calibration of Robstride joints."""

from __future__ import annotations

import contextlib
import sys
import threading
from collections.abc import Iterator
from pathlib import Path
from typing import Annotated, Any

import typer

from ..core.sweep_result import DEFAULT_SPAN_TOLERANCE_RAD
from ..errors import UsageError
from . import _common
from ._catalog import DEFAULT_DIRECTION_STEP_S
from ._options import DEFAULT_TOPIC, ReplayFrame, ReplayTopic, RobotProfile


@contextlib.contextmanager
def _web_view(
    enabled: bool, urdf: Path, port: int, inner: Any, threshold: float | None, span_tolerance: float
) -> Iterator[Any]:
    """``--view``: the sweep drawn on the robot in the browser (robocal.viewer.sweep_page), else ``inner``."""
    if not enabled:
        yield inner
        return
    from ..viewer.sweep_page import open_sweep_page

    web = open_sweep_page(
        urdf, inner=inner, port=port, threshold_rad=threshold, span_tolerance_rad=span_tolerance
    )
    _common.err_console.print(f"sweep view: {web.app.url}", markup=False)
    try:
        yield web
    finally:
        web.app.stop()


@contextlib.contextmanager
def _not_lost() -> Iterator[None]:
    """When the sweep's calibration could not be saved, show it (table, warnings, the file's text) first."""
    from ..workflows.sweep.output import SweepNotSavedError
    from ._sweep_view import print_sweep_warnings, result_table

    try:
        yield
    except SweepNotSavedError as exc:
        _common.console.print(result_table(exc.result))
        print_sweep_warnings(exc.result)
        if exc.calibration_text.strip() not in ("", "{}"):
            _common.err_console.print(
                f"the sweep's calibration was NOT saved; here it is ({exc.fmt}, on standard output):",
                markup=False,
            )
            sys.stdout.write(exc.calibration_text)
            sys.stdout.flush()
        raise


def sweep(
    urdf: Annotated[
        Path,
        typer.Option(
            "--urdf",
            help="The robot's URDF (expanded, not xacro): joint names and limits; directions and CAN ids from its "
            "<ros2_control> params when it has them, else from the calibration file or the robot profile "
            "(--robot, or recognised from the joint names; docs/profiles.md).",
        ),
    ],
    source: Annotated[
        str,
        typer.Option(
            "--source", help="sim:lite[?seed=N] (--auto: or sim:openarm), can:<interface>:<channel>[,<channel>...] or replay:<file>."
        ),
    ],
    out: Annotated[
        Path, typer.Option("--out", help="Calibration file to write (updated in place if it exists).")
    ],
    prior: Annotated[Path | None, typer.Option("--prior", help="Offsets kept for joints not swept.")] = None,
    threshold: Annotated[
        float | None,
        typer.Option("--threshold", help="Not-swept threshold, rad (default 0.5 two-sided, 0.05 one-sided)."),
    ] = None,
    span_tolerance: Annotated[
        float, typer.Option("--span-tolerance", help="Allowed |sweep - URDF span|, rad.")
    ] = DEFAULT_SPAN_TOLERANCE_RAD,
    report: Annotated[Path | None, typer.Option("--report", help="Write the JSON report here.")] = None,
    fmt: Annotated[
        str | None,
        typer.Option(
            "--format", help="lite-yaml or lite-json (default: from --out's extension, .json is lite-json)."
        ),
    ] = None,
    direction_check: Annotated[
        bool, typer.Option("--direction-check", help="Guided 'move toward +' check first.")
    ] = False,
    direction_time: Annotated[
        float,
        typer.Option("--direction-time", help="Seconds the direction check waits per joint for the motion."),
    ] = DEFAULT_DIRECTION_STEP_S,
    topic: ReplayTopic = DEFAULT_TOPIC,
    frame: ReplayFrame = None,
    robot: RobotProfile = None,
    yes: Annotated[
        bool,
        typer.Option(
            "--yes",
            "-y",
            help="Write every new offset without asking (on a terminal, a changed offset of a joint with a "
            "span_mismatch, no_overlap, offset_large or wrong_side warning is otherwise asked about).",
        ),
    ] = False,
    method: Annotated[
        str | None,
        typer.Option(
            "--method",
            help="one-sided (each joint into the profile's stop, as the robot's own procedure) or two-sided "
            "(both stops, bisection). Default: the profile's procedure, else two-sided.",
        ),
    ] = None,
    auto: Annotated[
        bool,
        typer.Option(
            "--auto",
            help="The joints find their own hard stops (Robstride, Damiao; the profile's auto_calibration section): "
            "asks to clear the workspace first (--yes skips), Ctrl-C makes every motor limp (docs/auto_calibration.md).",
        ),
    ] = False,
    joints: Annotated[
        str | None, typer.Option("--joints", help="--auto: calibrate only these joints (comma-separated).")
    ] = None,
    partial: Annotated[
        bool, typer.Option("--partial", help="--auto: write the joints that passed even if others failed.")
    ] = False,
    write_zero: Annotated[
        bool,
        typer.Option(
            "--write-zero",
            help="--auto: then move each joint to its 0 and store that as its motor's zero (Damiao 0xFE: one "
            "flash write per motor; what LeRobot, openarm_can and ROS 2 read).",
        ),
    ] = False,
    web_view: Annotated[
        bool, typer.Option("--view", help="Also draw the sweep on the robot in the browser (robocal[view]).")
    ] = False,
    view_port: Annotated[
        int, typer.Option("--view-port", help="TCP port of the --view page (0: any).")
    ] = 8080,
    verify: Annotated[
        bool,
        typer.Option(
            "--verify",
            help="--auto: touch the stops again and report per joint how far --out's offsets have drifted, degrees "
            "± uncertainty; nothing is written; exit 1 past --tolerance-deg.",
        ),
    ] = False,
    tolerance_deg: Annotated[
        float,
        typer.Option("--tolerance-deg", help="--verify: drift above which a joint is flagged, degrees."),
    ] = 2.0,
) -> None:
    """Hard-stop sweep calibration: sweep every joint between its stops, then write the homing offsets."""
    if auto:
        from ..workflows.autocal.sweep import SweepAutoRequest
        from ._autocal import make_confirm_start, sweep_auto

        if prior is not None or threshold is not None or method is not None or direction_check or frame:
            raise UsageError(
                "--auto finds the stops itself: --prior, --threshold, --method, --direction-check "
                "and --frame do not apply"
            )
        names = _common.parse_csv_list(joints, "--joints")  # "" or "a,,b": one error line, nothing moves
        confirm = make_confirm_start(yes)
        request = SweepAutoRequest(
            urdf,
            source,
            out,
            robot=robot,
            joints=names,
            report=report,
            fmt=fmt,
            partial=partial,
            verify=verify,
            tolerance_deg=tolerance_deg,
            write_zero=write_zero,
        )
        sweep_auto(request, confirm_start=confirm, view_port=view_port if web_view else None)
        return
    if joints is not None or partial or verify or write_zero:
        raise UsageError("--joints, --partial, --verify and --write-zero go with --auto")
    from ..workflows.sweep.job import SweepRequest, run_sweep
    from ._sweep_confirm import StdinLines, make_confirm, stdin_is_terminal, terminal
    from ._sweep_view import LiveView, print_sweep_warnings, result_table

    stop = threading.Event()
    lines = StdinLines(stop) if stdin_is_terminal() else None  # Enter finishes the sweep
    confirm = make_confirm(lines) if lines is not None and terminal() and not yes else None
    with (
        _not_lost(),
        LiveView(threshold_rad=threshold, span_tolerance_rad=span_tolerance) as live_view,
        _web_view(web_view, urdf, view_port, live_view, threshold, span_tolerance) as view,
    ):
        outcome = run_sweep(
            SweepRequest(
                urdf,
                source,
                out,
                prior=prior,
                threshold_rad=threshold,
                span_tolerance_rad=span_tolerance,
                report=report,
                fmt=fmt,
                direction_check=direction_check,
                direction_step_s=direction_time,
                topic=topic,
                frame=frame,
                robot=robot,
                method=method,
            ),
            view=view,
            stop=stop,
            confirm=confirm,
        )
    _common.console.print(result_table(outcome.result))
    print_sweep_warnings(outcome.result)
    for name, count in outcome.missing_samples.items():  # informational: NaN is legal in a JointState
        _common.err_console.print(
            f"note: {name}: {count} of {outcome.samples} samples had no position (NaN) and were skipped",
            markup=False,
        )
    robot_text = f", robot {outcome.robot}" if outcome.robot else ""
    _common.console.print(f"method: {outcome.method}{robot_text}", markup=False)
    _common.console.print(f"wrote {outcome.out} ({outcome.fmt})", markup=False)
    if outcome.report is not None:
        _common.console.print(f"wrote {outcome.report}", markup=False)
    raise typer.Exit(outcome.exit_code)


def register(app: typer.Typer) -> None:
    """Add ``sweep`` to the root app."""
    app.command("sweep")(sweep)
