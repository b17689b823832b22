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
    module = importlib.import_module("robocal.cli.kinematics" if identify else ROBOTS[robot])
    run = getattr(module, "run_demo", None)
    if run is None:
        raise UsageError(f"the {robot} demo is not available in this build")
    raise typer.Exit(int(run(robot, out)))


def register(app: typer.Typer) -> None:
    """Add ``demo`` to the root app."""
    app.command("demo")(demo)
