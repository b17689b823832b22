"""Shared pieces of the interruption tests: a child ``robocal`` that stops at a chosen import, and its run; a child
Python that reports its signal handlers."""

from __future__ import annotations

import os
import subprocess
import sys
import time
from pathlib import Path

SRC = Path(__file__).resolve().parents[2] / "src"

PAUSE_HOOK = '''
import os, sys, time

class _PauseAtImport:
    """Stops the process at the first import of $ROBOCAL_TEST_PAUSE_IMPORT (marker file, then a long sleep)."""

    def find_spec(self, name, path=None, target=None):
        if name == os.environ.get("ROBOCAL_TEST_PAUSE_IMPORT"):
            sys.meta_path.remove(self)
            with open(os.environ["ROBOCAL_TEST_PAUSE_MARKER"], "w") as fh:
                fh.write(str(os.getpid()))
            # short sleeps, not one long one: a signal that lands after the marker but before a sleep has begun is
            # handled at the next one (one long sleep held it for its whole length: a rare 120 s hang in CI)
            deadline = time.monotonic() + float(os.environ.get("ROBOCAL_TEST_PAUSE_S", "120"))
            while time.monotonic() < deadline:  # a signal's handler runs here
                time.sleep(0.05)
        return None

sys.meta_path.insert(0, _PauseAtImport())
'''
"""A ``sitecustomize`` that holds the child at one import: the signal lands exactly there, on any machine."""


def paused_child(
    argv: list[str], tmp: Path, module: str, *, program: list[str] | None = None, pause_s: float = 120
) -> tuple[subprocess.Popen[str], Path]:
    """Start ``robocal ARGV`` that stops at the first import of ``module``; returns it once it is there.

    Args:
        argv: The command's arguments.
        tmp: A folder for the hook and the marker (and the command's working folder).
        module: The module whose import holds the process.
        program: The program (default ``python -m robocal``).
        pause_s: How long it stays at the import (0: it only marks the instant it got there and goes on).

    Raises:
        AssertionError: The child did not reach the import within 120 s, or exited first.
    """
    hook = tmp / "hook"
    hook.mkdir(exist_ok=True)
    (hook / "sitecustomize.py").write_text(PAUSE_HOOK)
    marker = tmp / f"paused-{module}"
    marker.unlink(missing_ok=True)
    env = dict(
        os.environ,
        PYTHONPATH=os.pathsep.join([str(hook), str(SRC)]),
        ROBOCAL_TEST_PAUSE_IMPORT=module,
        ROBOCAL_TEST_PAUSE_MARKER=str(marker),
        ROBOCAL_TEST_PAUSE_S=str(pause_s),
        COLUMNS="200",
    )
    proc = subprocess.Popen(
        [*(program or [sys.executable, "-m", "robocal"]), *argv],
        cwd=tmp,
        env=env,
        stdin=subprocess.DEVNULL,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    deadline = time.monotonic() + 120  # hang guard: a loaded machine may take long to start Python
    while not marker.exists() or not marker.read_text():
        if proc.poll() is not None:
            _out, err = proc.communicate()
            raise AssertionError(f"robocal exited {proc.returncode} before importing {module}: {err}")
        assert time.monotonic() < deadline, f"robocal did not reach the import of {module} in 120 s"
        time.sleep(0.01)
    return proc, marker


def signalled_at_import(
    argv: list[str], tmp: Path, module: str, signum: int, *, program: list[str] | None = None
) -> tuple[int, str, str]:
    """Hold ``robocal ARGV`` at the first import of ``module`` (:func:`paused_child`), send it ``signum``.

    Returns:
        Its exit code, standard output and standard error once it has ended (bounded: 120 s).
    """
    proc, _ = paused_child(argv, tmp, module, program=program)
    proc.send_signal(signum)
    out, err = proc.communicate(timeout=120)
    return proc.returncode, out, err


def python_with_robocal(code: str) -> str:
    """Run ``python -c CODE`` with only robocal's sources on the path; its standard output (stderr on failure)."""
    r = subprocess.run(
        [sys.executable, "-c", code],
        capture_output=True,
        text=True,
        timeout=120,
        env={"PYTHONPATH": str(SRC)},
    )
    return r.stdout or r.stderr
