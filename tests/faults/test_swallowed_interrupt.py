"""A signal whose exception lands inside a finalizer is delivered again, not lost (issue 26).

A handler that raises runs wherever the main thread is when the signal lands. Inside a finalizer (an object's
``__del__`` or a weakref callback, run by the garbage collector between any two lines: an abandoned python-can bus
or serial port closing itself) Python cannot propagate the exception: it prints ``Exception ignored in …`` and goes
on. Before this, a Ctrl-C or SIGTERM there was lost and the command ran on to its end (the soak of 2026-11-29: an
OpenArm `sweep --auto` finished 14 s after a SIGINT at start-up, exit 1).
"""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

from robocal.cli import entry

CHILD = """
import signal, sys, time
from robocal.cli import entry
entry.install_command_handlers()
{guard}
class Closing:
    def __del__(self):
        signal.raise_signal(signal.{name})  # the handler runs in here: its exception cannot leave __del__
        for _ in range(1000):
            pass
try:
    {enter}
    Closing()
    for _ in range(500):  # the command goes on (10 s at most)
        time.sleep(0.02)
    print("ran on")
except KeyboardInterrupt as exc:
    print("interrupted", getattr(exc, "signum", 2))
"""


def _child(name: str, guard: str = "", enter: str = "pass") -> subprocess.CompletedProcess[str]:
    code = CHILD.format(name=name, guard=guard, enter=enter)
    return subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)


@pytest.mark.parametrize(("name", "signum"), [("SIGINT", 2), ("SIGTERM", 15)])
def test_a_signal_taken_inside_a_finalizer_still_interrupts_the_command(name: str, signum: int) -> None:
    done = _child(name)
    assert (done.stdout, done.stderr) == (f"interrupted {signum}\n", "")


def test_the_motion_guard_s_handler_is_covered_too() -> None:
    """SIGTERM while a :class:`MotionGuard` owns the signals: its ``SignalInterrupt`` is delivered again."""
    guard = (
        "from robocal.workflows.motion.guard import MotionGuard\n"
        "g = MotionGuard(limp=lambda: None)\n"
    )
    done = _child("SIGTERM", guard=guard, enter="g._install()")
    assert (done.stdout, done.stderr) == ("interrupted 15\n", "")


def test_other_exceptions_in_finalizers_are_still_reported() -> None:
    code = (
        "from robocal.cli import entry\nentry.install_command_handlers()\n"
        "class Bad:\n    def __del__(self):\n        raise ValueError('boom')\nBad()\nprint('ran on')\n"
    )
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert done.stdout == "ran on\n"
    assert "Exception ignored in" in done.stderr and "ValueError: boom" in done.stderr
    assert entry._redeliver_swallowed(object()) is False  # no exception at all: not ours


NOTED_INTERRUPT = """
import ctypes, sys
from robocal.cli import entry

def main():
    entry.quiet_after_interrupt()
    sys.stderr.write("error: interrupted\\n")
    # what CPython does when a KeyboardInterrupt leaves an evaluation of source text (exec or eval of a string, as
    # dataclasses and namedtuple do at every import): it notes it, the note outliving the except that caught it
    # until the next such evaluation (3.8-3.11 keep it in this exported int)
    ctypes.c_int.in_dll(ctypes.pythonapi, "_Py_UnhandledKeyboardInterrupt").value = 1
    return 130

entry.run_command(main)
"""


@pytest.mark.skipif(sys.version_info >= (3, 12), reason="3.12 moved the note into the runtime's state")
def test_an_interrupted_command_ends_with_its_code_even_with_cpythons_note_of_an_interrupt(tmp_path: Path) -> None:
    """The soak's exit -2 after robocal's own ``error: interrupted`` (issue 26, 7 trials over three sessions).

    Under ``python -m`` (how ``python -m robocal`` runs), CPython ends the process by SIGINT when its note of an
    unhandled ``KeyboardInterrupt`` is set at exit, although robocal caught it; an interrupted command now ends
    with its own code (reproduced before: ``python -m robocal check --help`` with Ctrl-C at random instants gave
    exit -2 after ``error: interrupted`` 4 times in 250).
    """
    (tmp_path / "noted_interrupt.py").write_text(NOTED_INTERRUPT)
    env = dict(os.environ, PYTHONPATH=os.pathsep.join([str(tmp_path), os.environ.get("PYTHONPATH", "")]))
    done = subprocess.run(
        [sys.executable, "-m", "noted_interrupt"], capture_output=True, text=True, timeout=120, cwd=tmp_path, env=env
    )
    assert (done.returncode, done.stderr) == (130, "error: interrupted\n")
