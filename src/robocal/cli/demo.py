"""``robocal demo``: the main job end to end on a simulated robot."""

from __future__ import annotations

import importlib
from pathlib import Path

import typer

from ..errors import UsageError

ROBOTS: dict[str, str] = {
    "lite": "robocal.cli.sweep",
    "so101": "robocal.cli.lerobot",
    "koch": "robocal.cli.lerobot",
    "ur3": "robocal.cli.ur",
    "ur5": "robocal.cli.ur",
    "ur10": "robocal.cli.ur",
    "ur3e": "robocal.cli.ur",
    "ur5e": "robocal.cli.ur",
    "ur10e": "robocal.cli.ur",
    "ur16e": "robocal.cli.ur",
    "ur20": "robocal.cli.ur",
    "ur30": "robocal.cli.ur",
}
"""Demo robot → CLI module providing ``run_demo(robot, out_dir) -> int``."""

IDENTIFY_ROBOTS: tuple[str, ...] = ("so101", "koch")
"""Robots ``demo --identify`` simulates (``robocal.cli.kinematics.run_demo``)."""


def demo(
    robot: str = typer.Option("lite", "--robot", help="Simulated robot: " + ", ".join(ROBOTS) + "."),
    out: Path | None = typer.Option(
        None, "--out", help="Folder for the files written (default: a temporary one)."
    ),
    identify: bool = typer.Option(
        False, "--identify", help="Kinematic identification instead (so101, koch): simulate, identify, check."
    ),
    view: bool = typer.Option(
        False,
        "--view",
        help="Then show the calibrated simulated Lite in the browser (robocal view; Ctrl-C to stop).",
    ),
    port: int = typer.Option(8080, "--port", help="With --view: TCP port of the page (0: any free one)."),
    auto: bool = typer.Option(
        False, "--auto", help="The simulated joints find their own hard stops (lite; docs/auto_calibration.md)."
    ),
) -> None:
    """Calibrate a simulated robot end to end (default: the Lite humanoid's 14 Robstride joints)."""
    robot = robot.strip().lower()
    if robot not in ROBOTS:
        raise UsageError(f"unknown demo robot {robot!r}; valid: {', '.join(ROBOTS)}")
    if out is not None:
        if out.exists() and not out.is_dir():
            raise UsageError(f"--out {out} is a file; give a folder for the demo's files")
        try:
            out.mkdir(parents=True, exist_ok=True)
        except OSError as exc:
            raise UsageError(f"cannot create --out folder {out}: {exc.strerror or exc}") from None
    if identify and robot not in IDENTIFY_ROBOTS:
        raise UsageError(f"--identify works with {', '.join(IDENTIFY_ROBOTS)}, not {robot!r}")
    if auto:
        if identify or view:
            raise UsageError("--auto is its own demo; it does not go with --identify or --view")
        from ._autocal import run_auto_demo

        raise typer.Exit(int(run_auto_demo(robot, out)))
    if view:
        if robot != "lite" or identify:
            raise UsageError(
                "--view shows the Lite demo; for a LeRobot arm use "
                "`robocal view --urdf URDF --lerobot-port sim --robot so101_follower --calibration FILE`"
            )
        raise typer.Exit(_demo_view(out, port))
    module = importlib.import_module("robocal.cli.kinematics" if identify else ROBOTS[robot])
    run = getattr(module, "run_demo", None)
    if run is None:
        raise UsageError(f"the {robot} demo is not available in this build")
    raise typer.Exit(int(run(robot, out)))


def _demo_view(out: Path | None, port: int) -> int:
    """Run the Lite sweep demo, then serve the calibrated simulated Lite; the worse of the two exit codes."""
    import tempfile

    from ..viewer.app import check_port_free
    from ..viewer.demo import lite_view_options
    from . import sweep, view

    check_port_free("127.0.0.1", port)  # before the sweep, not after it
    with tempfile.TemporaryDirectory(prefix="robocal-demo-") as tmp:
        folder = out if out is not None else Path(tmp)
        code = int(sweep.run_demo("lite", folder))
        if code not in (0, 1):
            return code
        opts = lite_view_options(folder / "calibration.yaml", sweep.DEMO_SOURCE, port=port)
        return max(code, view.serve(opts))


def register(app: typer.Typer) -> None:
    """Add ``demo`` to the root app."""
    app.command("demo")(demo)
