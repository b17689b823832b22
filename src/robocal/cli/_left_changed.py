"""What a previous run left changed on a LeRobot arm's bus: said, and offered back (issue 26).

A guarded run that could not finish its restore (a lost device, SIGKILL, a power cut) keeps its register snapshot
in robocal's state folder (:mod:`robocal.workflows.motion.snapshot`). The next ``lerobot`` command that opens that
port calls :func:`offer_restore`: one ``note:`` line names the run and every register it left changed (motor,
name, value now and before); on a terminal it asks whether to write them back, otherwise it says how
(``robocal lerobot restore-previous``).
"""

from __future__ import annotations

import sys
from typing import TYPE_CHECKING, Any

import typer

from . import _common
from ._lerobot_render import status

if TYPE_CHECKING:
    from ..core.lerobot import RobotSpec

__all__ = ["offer_restore", "restore_previous"]


def _note(text: str) -> None:
    sys.stderr.write(f"note: {text}\n")
    sys.stderr.flush()


def offer_restore(bus: Any, spec: RobotSpec, port: str, arm: Any = None) -> None:
    """Say what a previous run left changed on ``port`` and offer to write it back (nothing for a simulated arm)."""
    if arm is not None:
        return
    from ..workflows.lerobot import find_left_over, restore_left_over

    left = find_left_over(bus, spec, port)
    if left is None:
        return
    _note(left.describe())
    how = f"`robocal lerobot restore-previous --robot {spec.name} --port {port}`"
    if not (sys.stdin.isatty() and sys.stderr.isatty()):
        _note(f"not written back (no terminal to ask); {how} writes the previous values back")
        return
    if typer.confirm("Write the previous values back now?", default=True, err=True):
        _note(restore_left_over(bus, spec, left, status).summary())
    else:
        _note(f"left as it is; {how} writes the previous values back later")


def restore_previous(robot: str, port: str) -> None:
    """``lerobot restore-previous``: write back what a previous run left changed on ``port``; exit 0 or 3."""
    from ..workflows.lerobot import find_left_over, open_arm, restore_left_over, robot_spec

    spec = robot_spec(robot)
    with open_arm(spec, port) as (bus, _arm):
        left = find_left_over(bus, spec, port)
        if left is None:
            _common.console.print(f"nothing left changed on {port}", markup=False)
            raise typer.Exit(0)
        _note(left.describe())
        report = restore_left_over(bus, spec, left, status)
    _common.console.print(report.summary(), markup=False)
    raise typer.Exit(3 if report.not_restored else 0)
