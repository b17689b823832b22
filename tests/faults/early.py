"""A signal at a random instant from a ``robocal`` process's start, and what it did (issue 26 item 1).

Used by ``tests/faults/test_early_signals.py`` (a few instants) and ``python benchmarks/run.py faults --early N``
(many, with the outcome per 50 ms after the start: how long Python's own start-up is on this machine).
"""

from __future__ import annotations

import os
import random
import signal
import subprocess
import sys
import time
from collections import Counter
from pathlib import Path

SRC = Path(__file__).resolve().parents[2] / "src"
LINES = {
    signal.SIGINT: "error: interrupted",
    signal.SIGTERM: "error: interrupted by SIGTERM",
    signal.SIGHUP: "error: interrupted by SIGHUP",
    signal.SIGQUIT: "error: interrupted by SIGQUIT",
}
ROBOCAL = "robocal"  # robocal's handlers: one line, 128 + signum
FINISHED = "finished"  # the command ended before the signal (exit 0)
PYTHON = "python"  # before robocal's first line: Python's default action or its KeyboardInterrupt


def programs(folder: Path) -> list[list[str]]:
    """``python -m robocal`` and a console script as pip generates it (written into ``folder``)."""
    script = folder / "robocal"
    script.write_text("import re\nimport sys\nfrom robocal.cli.entry import run\nsys.exit(run())\n")
    return [[sys.executable, "-m", "robocal"], [sys.executable, str(script)]]


def outcome(folder: Path, program: list[str], signum: int, delay_s: float) -> tuple[str, str]:
    """Run ``robocal check --help``, send ``signum`` ``delay_s`` after the start; (class, what happened).

    The class is :data:`ROBOCAL`, :data:`FINISHED`, :data:`PYTHON`, or ``wrong`` (a traceback through robocal's
    files, a second line, another exit code).
    """
    proc = subprocess.Popen(
        [*program, "check", "--help"],
        cwd=folder,
        env=dict(os.environ, PYTHONPATH=str(SRC)),
        stdin=subprocess.DEVNULL,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    time.sleep(delay_s)  # the instant is the random variable, not a wait for something to happen
    proc.send_signal(signum)
    out, err = proc.communicate(timeout=300)
    code = proc.returncode
    seen = (
        f"{signal.Signals(signum).name} {delay_s * 1000:.0f} ms after the start: exit {code}, {err[-1500:]!r}"
    )
    if str(SRC) in err:  # a traceback through robocal's own files
        return "wrong", seen
    if code == 128 + signum:  # (the help page may have been printed in part when the signal came)
        return (ROBOCAL, seen) if err == LINES[signum] + "\n" else ("wrong", seen)
    if code == 0:
        return (FINISHED, seen) if "Usage" in out and not err else ("wrong", seen)
    if code == -signum or (signum == signal.SIGINT and "KeyboardInterrupt" in err):
        return PYTHON, seen
    return "wrong", seen


def measure(trials: int, seed: int, max_delay_s: float, folder: Path) -> str:
    """``trials`` random instants in ``[0, max_delay_s]``: the classes per 50 ms, and every wrong one."""
    rng = random.Random(seed)
    progs = programs(folder)
    rows: Counter[tuple[int, str]] = Counter()
    wrong = []
    for _ in range(trials):
        delay_s = rng.uniform(0.0, max_delay_s)
        cls, seen = outcome(folder, rng.choice(progs), rng.choice(list(LINES)), delay_s)
        rows[(int(delay_s * 20), cls)] += 1
        if cls == "wrong":
            wrong.append(seen)
    lines = [f"{'ms after start':>15s} {PYTHON:>8s} {ROBOCAL:>8s} {FINISHED:>8s} {'wrong':>8s}"]
    for b in sorted({b for b, _ in rows}):
        cells = "".join(f"{rows[(b, c)]:>9d}" for c in (PYTHON, ROBOCAL, FINISHED, "wrong"))
        lines.append(f"{b * 50:>6d}-{b * 50 + 50:<8d}{cells}")
    return "\n".join([*lines, *wrong])
