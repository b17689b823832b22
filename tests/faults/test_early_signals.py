"""A signal before the command line is imported, or while a command runs: one line, the signal's exit code.

Issue 26: Ctrl-C in the first ~0.8 s of any command printed a raw ``KeyboardInterrupt`` traceback, and SIGTERM or
SIGHUP ended the process without a word. The child is held at a chosen import by a ``sitecustomize`` hook, so the
signal lands inside the import on any machine, however loaded.
"""

from __future__ import annotations

import signal
import subprocess
import sys
from pathlib import Path

import pytest

from .conftest import python_with_robocal, signalled_at_import

SIGNALS = [
    (signal.SIGINT, 130, "error: interrupted"),
    (signal.SIGTERM, 143, "error: interrupted by SIGTERM"),
    (signal.SIGHUP, 129, "error: interrupted by SIGHUP"),
    (signal.SIGQUIT, 131, "error: interrupted by SIGQUIT"),
]


SLOW = pytest.mark.slow  # a Python start-up each (2-5 s on a loaded machine)


@pytest.mark.parametrize(
    ("signum", "code", "line"),
    [SIGNALS[0], *(pytest.param(*s, marks=SLOW) for s in SIGNALS[1:])],
    ids=["SIGINT", "SIGTERM", "SIGHUP", "SIGQUIT"],
)
# typer: the first heavy import; robocal.cli.health: the last command module the command line imports (a help page
# imports no numpy since the lazy start of issue 28)
@pytest.mark.parametrize("module", ["typer", pytest.param("robocal.cli.health", marks=SLOW)])
def test_signal_while_importing_prints_one_line(
    tmp_path: Path, signum: int, code: int, line: str, module: str
) -> None:
    returncode, out, err = signalled_at_import(["check", "--help"], tmp_path, module, signum)
    assert (returncode, err, out) == (code, line + "\n", "")


@pytest.mark.parametrize("program", ["-m", "script"])
def test_signal_at_robocal_s_first_import_prints_one_line(tmp_path: Path, program: str) -> None:
    """The first import robocal's own code makes (``robocal.errors``): its handlers are in place before it.

    On main before, they came after ``robocal.errors``, ``robocal.cli`` and ``collections`` were imported: a
    Ctrl-C there printed a ``KeyboardInterrupt`` traceback through robocal's files, a SIGTERM ended it silently.
    """
    script = tmp_path / "robocal"  # what pip generates for the console script
    script.write_text("import re\nimport sys\nfrom robocal.cli.entry import run\nsys.exit(run())\n")
    argv = None if program == "-m" else [sys.executable, str(script)]
    for signum, code, line in (SIGNALS[0], SIGNALS[1]):
        returncode, out, err = signalled_at_import(["check", "--help"], tmp_path, "robocal.errors", signum, program=argv)
        assert (returncode, err, out) == (code, line + "\n", ""), signum


def test_importing_robocal_installs_no_handler() -> None:
    """Only the ``robocal`` program installs handlers at import: a program that imports robocal keeps its own."""
    code = "import signal, robocal; print(signal.getsignal(signal.SIGINT) is signal.default_int_handler, signal.getsignal(signal.SIGTERM) == signal.SIG_DFL)"
    assert python_with_robocal(code) == "True True\n"


@SLOW
def test_old_console_script_is_covered_too(tmp_path: Path) -> None:
    """A ``robocal`` script generated before the new entry point (``from robocal.cli.main import run``)."""
    script = tmp_path / "robocal"
    script.write_text("import sys\nfrom robocal.cli.main import run\nsys.exit(run())\n")
    program = [sys.executable, str(script)]
    returncode, _out, err = signalled_at_import(["check", "--help"], tmp_path, "typer", signal.SIGINT, program=program)
    assert (returncode, err) == (130, "error: interrupted\n")


@SLOW
@pytest.mark.parametrize(("signum", "code", "line"), SIGNALS, ids=["SIGINT", "SIGTERM", "SIGHUP", "SIGQUIT"])
def test_signal_while_a_command_opens_its_source(tmp_path: Path, signum: int, code: int, line: str) -> None:
    """The sweep is running (its CAN source being opened): one line, the signal's code, nothing written."""
    from robocal.backends.sim.lite import lite_urdf_text

    (tmp_path / "lite.urdf").write_text(lite_urdf_text())
    argv = ["sweep", "--urdf", "lite.urdf", "--source", "sim:lite?seed=3", "--out", "cal.yaml"]
    returncode, _out, err = signalled_at_import(argv, tmp_path, "can", signum)
    assert (returncode, err) == (code, line + "\n")
    assert not (tmp_path / "cal.yaml").exists()
    assert not [p.name for p in tmp_path.iterdir() if p.name.startswith(".rc-")]


def test_ignored_sighup_stays_ignored(tmp_path: Path) -> None:
    """``nohup robocal ...``: the parent ignores SIGHUP, and so does robocal (a closed terminal must not stop it)."""
    code = (
        "import signal, sys; signal.signal(signal.SIGHUP, signal.SIG_IGN); "
        "from robocal.cli import entry; entry.install_startup_handlers(); "
        "print(signal.getsignal(signal.SIGHUP) == signal.SIG_IGN, signal.getsignal(signal.SIGTERM) is not None)"
    )
    assert python_with_robocal(code) == "True True\n"


@SLOW
def test_signals_at_random_instants_from_the_start(tmp_path: Path) -> None:
    """A signal at a random instant from the process's start: robocal's line, a finished run, or Python's own.

    The window before robocal's first line (the interpreter, its ``site`` and ``runpy`` imports) is Python's:
    there SIGINT gives Python's ``KeyboardInterrupt`` (or the default action, before Python installs its handler)
    and SIGTERM/SIGHUP/SIGQUIT the default action. Once robocal's package starts importing, every signal ends with
    its one line and ``128 + signum``; no traceback ever shows a frame of robocal's code. More instants, with the
    outcome per 50 ms: ``python benchmarks/run.py faults --early 300``.
    """
    import random

    from .early import FINISHED, LINES, PYTHON, ROBOCAL, outcome, programs

    rng = random.Random(2611)
    progs = programs(tmp_path)
    seen = [
        outcome(tmp_path, rng.choice(progs), rng.choice(list(LINES)), rng.uniform(0, 1.5)) for _ in range(10)
    ]
    assert [s for cls, s in seen if cls not in (ROBOCAL, FINISHED, PYTHON)] == []


LATE_SIGNAL = """
import signal
from robocal.cli import entry

real = entry._block_signals_until_exit
calls = []

def signal_lands_first():  # a SIGINT that arrived as main() returned: its handler runs at the next call
    if not calls:
        calls.append(1)
        signal.raise_signal(signal.{name})  # Python runs the handler here, before the blocking is done
    real()

entry._block_signals_until_exit = signal_lands_first
entry.install_startup_handlers()

def main():
    print("the command's last line", flush=True)
    return {code}

entry.run_command(main)
"""


@pytest.mark.parametrize(("name", "code"), [("SIGINT", 0), ("SIGTERM", 1)])
def test_a_signal_as_the_finished_command_returns_is_ignored(name: str, code: int) -> None:
    """The command had finished (written, printed) when the signal came, before the handlers were blocked: the
    process exits with the command's code, no traceback (it was killed by SIGINT: the rare exit -2 of
    tests/faults/test_sweep_interrupts.py)."""
    import subprocess

    from .conftest import SRC

    r = subprocess.run(
        [sys.executable, "-c", LATE_SIGNAL.format(name=name, code=code)],
        capture_output=True,
        text=True,
        timeout=120,
        env={"PYTHONPATH": str(SRC)},
    )
    assert (r.returncode, r.stdout, r.stderr) == (code, "the command's last line\n", "")


def test_a_trial_s_robocal_starts_with_no_signal_blocked_whatever_thread_forks_it() -> None:
    """A child inherits the forking thread's signal mask: the harness's children start with an empty one."""
    import threading

    from .harness import _default_signals

    out: list[str] = []

    def spawn() -> None:
        signal.pthread_sigmask(signal.SIG_BLOCK, {signal.SIGINT, signal.SIGTERM})
        cmd = [sys.executable, "-c", "print(open('/proc/self/status').read())"]
        out.append(subprocess.run(cmd, capture_output=True, text=True, preexec_fn=_default_signals).stdout)
        plain = subprocess.run(cmd, capture_output=True, text=True).stdout
        out.append(plain)

    t = threading.Thread(target=spawn)
    t.start()
    t.join()
    masks = [int(next(ln for ln in o.splitlines() if ln.startswith("SigBlk:")).split()[1], 16) for o in out]
    sigint = 1 << (signal.SIGINT - 1)
    assert masks[1] & sigint  # without it the child's SIGINT would stay pending for good
    assert masks[0] == 0
