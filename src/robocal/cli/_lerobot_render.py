"""Terminal rendering of ``robocal lerobot``: operator prompts, the live range table, tables and messages."""

from __future__ import annotations

import contextlib
import sys
import threading
import time
from collections.abc import Callable
from typing import TYPE_CHECKING

import typer
from rich.live import Live
from rich.table import Table

from . import _common

if TYPE_CHECKING:
    from ..core.lerobot import MotorCalibration, RobotSpec

__all__ = [
    "ConsoleOperator",
    "interrupted",
    "print_calibration",
    "print_range_warnings",
    "status",
    "sweep_renderer",
]


def interrupted(exc: KeyboardInterrupt, restored: str, not_restored: str = "") -> typer.Exit:
    """Print the one ``error: interrupted`` line; exit 130 (Ctrl-C), 143 (SIGTERM), 129 (SIGHUP), 131 (SIGQUIT).

    The workflows re-raise Ctrl-C with the motors they could not restore as its argument; then that is shown.
    """
    from .entry import interrupted_text
    from .main import written_this_command

    if written_this_command():  # the run had finished: its file is whole, the motors
        raise exc  # hold what it says; main's line names the file ("interrupted … after writing FILE (complete)")
    what = f"{exc}{not_restored}" if exc.args else restored
    code = _common.interrupt_exit_code(exc)
    _common.print_error(f"{interrupted_text(code - 128)}: {what}")
    return typer.Exit(code)


def print_range_warnings(spec: RobotSpec, cals: dict[str, MotorCalibration]) -> list[str]:
    """Print (and return) one warning per motor whose range lies beyond one turn (LeRobot accepts those)."""
    from ..workflows.lerobot import range_warnings as beyond_one_turn

    found = beyond_one_turn(spec, cals)
    _common.print_warnings(found)
    return found


def status(message: str) -> None:
    """One plain status line on standard error (e.g. while the EEPROM is being restored)."""
    sys.stderr.write(message + "\n")
    sys.stderr.flush()


class ConsoleOperator:
    """A human at a terminal: ``input()`` for prompts; the sweep ends when ENTER is pressed."""

    def __init__(self) -> None:
        self._done = threading.Event()

    def prompt(self, stage: str, message: str) -> None:
        """Print the message and wait for ENTER (the sweep prompt returns at once; ENTER ends the sweep)."""
        if stage == "sweep":
            _common.err_console.print(message)
            self._done.clear()

            def wait() -> None:
                with contextlib.suppress(EOFError, OSError):
                    sys.stdin.readline()
                self._done.set()

            from ..workflows.motion.guard import start_signal_free  # signals go to the main thread's handlers

            start_signal_free(threading.Thread(target=wait, daemon=True))
            return
        _common.err_console.print(message)
        sys.stdin.readline()

    def sweep_step(self) -> bool:
        """True once ENTER was pressed; paces the loop at about 50 Hz like LeRobot."""
        time.sleep(0.02)
        return self._done.is_set()


def sweep_renderer() -> tuple[Callable[[object], None], Callable[[], None]]:
    """A live rich table on a terminal, otherwise one plain line every 10 readings."""
    from ..workflows.lerobot import RangeView

    live: Live | None = None
    last: list[RangeView] = []

    def table(view: RangeView) -> Table:
        t = Table(title=f"range of motion (reading {view.step})")
        for col in ("motor", "min", "present", "max"):
            t.add_column(col, justify="right" if col != "motor" else "left")
        for n, p, lo, hi in zip(view.names, view.present, view.minimum, view.maximum, strict=True):
            t.add_row(n, str(lo), str(p), str(hi))
        return t

    def update(view: object) -> None:
        nonlocal live
        assert isinstance(view, RangeView)
        last[:] = [view]
        if _common.err_console.is_terminal:
            if live is None:
                live = Live(table(view), console=_common.err_console, refresh_per_second=10)
                live.start()
            else:
                live.update(table(view))
        elif view.step % 10 == 0:
            parts = [
                f"{n} {lo}..{hi}" for n, lo, hi in zip(view.names, view.minimum, view.maximum, strict=True)
            ]
            _common.err_console.print(f"reading {view.step}: " + ", ".join(parts))

    def close() -> None:
        """Stop the live table or print the last plain line; idempotent (nothing is printed twice)."""
        nonlocal live
        if live is not None:
            live.stop()
            live = None
        elif last:
            v = last[0]
            parts = [f"{n} {lo}..{hi}" for n, lo, hi in zip(v.names, v.minimum, v.maximum, strict=True)]
            _common.err_console.print(f"reading {v.step}: " + ", ".join(parts))
        last.clear()

    return update, close


def print_calibration(cals: dict[str, MotorCalibration]) -> None:
    t = Table(title="calibration")
    for col in ("motor", "id", "drive_mode", "homing_offset", "range_min", "range_max"):
        t.add_column(col)
    for n, c in cals.items():
        t.add_row(n, str(c.id), str(c.drive_mode), str(c.homing_offset), str(c.range_min), str(c.range_max))
    _common.console.print(t)


