"""The terminal side of ``robocal sweep``: Enter to finish, and the prompt before a risky offset replaces a prior one."""

from __future__ import annotations

import math
import queue
import sys
import threading
from collections.abc import Callable, Sequence

from rich.table import Table

from ..core.sweep_result import SweepResult
from ..workflows.sweep.output import CONFIRM_CODES
from . import _common

__all__ = ["ANSWERS", "StdinLines", "confirm_table", "make_confirm", "stdin_is_terminal", "terminal"]


class StdinLines:
    """The one reader of standard input on a terminal: a thread puts each line in a queue.

    During the sweep the first line (Enter) sets ``stop``; afterwards the confirmation prompt takes the lines
    from the same queue, so no thread left blocked in ``readline`` swallows the person's answer.
    """

    def __init__(self, stop: threading.Event) -> None:
        self.stop = stop
        self.lines: queue.Queue[str | None] = queue.Queue()
        self.prompting = False
        from ..workflows.motion.guard import start_signal_free  # signals go to the main thread's handlers

        start_signal_free(threading.Thread(target=self._run, name="robocal-stdin", daemon=True))

    def _run(self) -> None:
        while True:
            try:
                line = sys.stdin.readline()
            except Exception:
                line = ""
            if not line:
                self.lines.put(None)  # end of input
                return
            if self.prompting:
                self.lines.put(line)
            else:
                self.stop.set()  # Enter during the sweep: finish

    def ask(self, question: str) -> str | None:
        """Print ``question`` and wait for a line (None at end of input); Ctrl-C stays possible while waiting."""
        self.prompting = True
        _common.console.print(question, end="", markup=False)
        sys.stdout.flush()
        while True:
            try:
                line = self.lines.get(timeout=0.2)
            except queue.Empty:
                continue
            return None if line is None else line.strip()


def stdin_is_terminal() -> bool:
    try:
        return sys.stdin.isatty()
    except (AttributeError, ValueError):
        return False


def terminal() -> bool:
    """Whether a person is at a terminal (standard input and output both TTYs)."""
    try:
        return sys.stdin.isatty() and sys.stdout.isatty()
    except (AttributeError, ValueError):
        return False


def confirm_table(result: SweepResult, names: Sequence[str]) -> Table:
    """Old vs new offset of the joints whose change needs a yes, with the warning that makes it doubtful."""
    t = Table(title="these joints have a warning; replace their previous offset? (rad, motor frame)")
    for col in ("joint", "previous", "new", "change", "warning"):
        t.add_column(col, justify="left" if col in ("joint", "warning") else "right")
    for name in names:
        j = result[name]
        prev = float(j.previous_homing_offset) if j.previous_homing_offset is not None else math.nan
        t.add_row(
            name,
            f"{prev:+.4f}",
            f"{j.homing_offset:+.4f}",
            f"{j.homing_offset - prev:+.4f}",
            ", ".join(c for c in j.warnings if c in CONFIRM_CODES),
        )
    return t


ANSWERS = {
    "y": "yes",
    "yes": "yes",
    "n": "no",
    "no": "no",
    "": "no",
    "a": "all",
    "all": "all",
    "none": "none",
}


def make_confirm(lines: StdinLines) -> Callable[[SweepResult, Sequence[str]], set[str]]:
    """The terminal prompt: show old vs new, then ask per joint (y / n, or all / none for the rest)."""

    def confirm(result: SweepResult, names: Sequence[str]) -> set[str]:
        con = _common.console
        con.print(confirm_table(result, names))
        for name in names:
            for code in result[name].warnings:
                if code in CONFIRM_CODES:
                    _common.print_warning(f"{name}: {code}: {result.explain(name, code)}")
        accepted: set[str] = set()
        for k, name in enumerate(names):
            j = result[name]
            question = (
                f"{name}: replace {j.previous_homing_offset:+.4f} with {j.homing_offset:+.4f} rad? "
                "[y]es / [n]o, keep it (default) / [a]ll / none: "
            )
            while True:
                line = lines.ask(question)
                answer = "none" if line is None else ANSWERS.get(line.lower())
                if answer is not None:
                    break
                con.print("please answer y, n, all or none", markup=False)
            if answer == "yes":
                accepted.add(name)
            elif answer in ("all", "none"):
                if answer == "all":
                    accepted.update(names[k:])
                break
        kept = [n for n in names if n not in accepted]
        if kept:
            con.print(f"keeping the previous offset of {', '.join(kept)}", markup=False)
        return accepted

    return confirm
