"""The ``robocal`` program's first code: signal handling before the heavy imports, then :func:`main.main`.

Importing the command line (typer, rich, numpy, every command) takes up to a second on a loaded machine. A signal
in that time used to print a raw ``KeyboardInterrupt`` traceback (SIGINT) or end the process without a word
(SIGTERM, SIGHUP). :func:`run` is the console script and ``python -m robocal``: it imports the standard library
only, so its handlers are in place within milliseconds of the interpreter starting:

* while importing (:func:`install_startup_handlers`): nothing has been opened, moved or written yet, so a
  signal prints one ``error: interrupted`` line and ends the process at once with ``128 + signal number``
  (SIGINT 130, SIGTERM 143, SIGHUP 129);
* while a command runs (:func:`install_command_handlers`): SIGINT raises ``KeyboardInterrupt`` as usual, SIGTERM
  and SIGHUP raise :class:`robocal.errors.SignalInterrupt` (a ``KeyboardInterrupt``), so every path that makes
  motors limp or restores registers on Ctrl-C runs for them too; the exit code says which signal came first.

A signal the parent set to be ignored (``nohup`` ignores SIGHUP, a background job of a non-interactive shell
ignores SIGINT) stays ignored. This module must import nothing beyond the standard library and
:mod:`robocal.errors`.
"""

from __future__ import annotations

import os
import signal
import sys
from collections.abc import Callable
from types import FrameType
from typing import NoReturn

from ..errors import SignalInterrupt

__all__ = [
    "HANDLED_SIGNALS",
    "exit_code_for",
    "first_signal",
    "install_command_handlers",
    "install_startup_handlers",
    "interrupted_text",
    "protect_startup_if_program",
    "quiet_after_interrupt",
    "run",
    "run_command",
    "signal_name",
]

HANDLED_SIGNALS: tuple[int, ...] = tuple(
    int(s)
    for s in (getattr(signal, n, None) for n in ("SIGINT", "SIGTERM", "SIGHUP", "SIGQUIT"))
    if s is not None
)
"""Signals that end a command with one line: SIGINT (Ctrl-C), SIGTERM (``kill``), SIGHUP (terminal closed),
SIGQUIT (Ctrl-\\; Python's default would dump core)."""

_received: list[int] = []
_installed = False


def signal_name(signum: int) -> str:
    """``SIGTERM`` for 15 (the number as text when the platform has no name for it)."""
    try:
        return signal.Signals(signum).name
    except ValueError:
        return f"signal {signum}"


def interrupted_text(signum: int) -> str:
    """The one line a signal ends a command with: ``interrupted`` (Ctrl-C) or ``interrupted by SIGTERM``."""
    return "interrupted" if signum == signal.SIGINT else f"interrupted by {signal_name(signum)}"


def exit_code_for(signum: int) -> int:
    """The shell's convention for a process ended by a signal: ``128 + signum`` (SIGINT 130, SIGTERM 143)."""
    return 128 + int(signum)


def first_signal() -> int | None:
    """The first signal :func:`run`'s handlers received in this process (None: none, or not run as a program)."""
    return _received[0] if _received else None


def _exit_now(signum: int, frame: FrameType | None) -> None:
    """Startup handler: nothing is open yet; one line and exit, no Python code after this (no traceback)."""
    try:
        os.write(2, f"error: {interrupted_text(signum)}\n".encode())
    finally:
        os._exit(exit_code_for(signum))


def _raise_interrupt(signum: int, frame: FrameType | None) -> None:
    """Command handler: record the signal and interrupt the main thread's code where it is."""
    _received.append(signum)
    if signum == signal.SIGINT:
        raise KeyboardInterrupt
    raise SignalInterrupt(signum)


def _record_only(signum: int, frame: FrameType | None) -> None:
    _received.append(signum)


def _install(handler: Callable[[int, FrameType | None], None]) -> None:
    for signum in HANDLED_SIGNALS:
        try:
            if signal.getsignal(signum) == signal.SIG_IGN:
                continue  # the parent asked for it to be ignored (nohup, a background job)
            signal.signal(signum, handler)
        except (OSError, ValueError):  # not the main thread, or not settable here
            continue


def install_startup_handlers() -> None:
    """Until the command line is imported: a signal prints one line and exits ``128 + signum`` at once."""
    global _installed
    _installed = True
    _install(_exit_now)


def install_command_handlers() -> None:
    """While a command runs: SIGINT raises ``KeyboardInterrupt``, SIGTERM/SIGHUP :class:`SignalInterrupt`.

    Also :func:`_redeliver_swallowed`: a signal's exception raised inside a finalizer is delivered again.
    """
    global _installed
    _installed = True
    _install(_raise_interrupt)
    if getattr(sys.unraisablehook, "__wrapped__", None) is None:
        previous = sys.unraisablehook

        def hook(unraisable: object) -> None:
            if not _redeliver_swallowed(unraisable):
                previous(unraisable)  # type: ignore[arg-type]

        hook.__wrapped__ = previous  # type: ignore[attr-defined]
        sys.unraisablehook = hook


def _redeliver_swallowed(unraisable: object) -> bool:
    """Deliver again a signal whose exception Python swallowed; True when ``unraisable`` was one.

    A handler that raises runs wherever the main thread is when the signal lands; inside a finalizer (an object's
    ``__del__``, a weakref callback, run by the garbage collector between any two lines, e.g. an abandoned
    python-can bus or serial port being closed) the exception cannot propagate: Python prints ``Exception ignored
    in …`` and goes on, the signal lost — the command ran to its end after a Ctrl-C. Here a short-lived thread
    trips it again for the main thread a moment later (tripped from here, the handler would run inside this hook,
    swallowed again), whose handler then runs at its next line, outside the finalizer; a finalizer that takes it
    again brings it back here. Not printed: the interruption is reported once, where it ends the command.
    """
    exc = getattr(unraisable, "exc_value", None)
    if not isinstance(exc, KeyboardInterrupt):
        return False
    signum = int(getattr(exc, "signum", None) or signal.SIGINT)
    import _thread
    import time

    def again() -> None:
        time.sleep(0.002)  # the main thread leaves the finalizer meanwhile (if not, it comes back here)
        try:
            _thread.interrupt_main(signal.Signals(signum))
        except (ValueError, OSError):  # a signal this platform cannot simulate
            return

    try:  # the low-level start: threading's waits for the thread, and the handler would run in that wait
        _thread.start_new_thread(again, ())
    except RuntimeError:  # the interpreter is shutting down: the command is over
        return False
    return True


def quiet_after_interrupt() -> None:
    """After an interruption was caught: further signals are recorded, not raised (the process is ending).

    Does nothing unless :func:`run` installed the handlers (a test calling ``main()`` keeps its own Ctrl-C).
    """
    if _installed:
        _install(_record_only)
        # a bus the interruption caught half-open is collected at exit; python-can's "was not properly shut
        # down" would follow the one line (the process is ending: every bus closes with it)
        import logging

        logging.getLogger("can").setLevel(logging.CRITICAL)


def protect_startup_if_program() -> None:
    """Install the startup handlers when this process is the ``robocal`` program (and nothing else).

    For a console script generated before :func:`run` was the entry point (``from robocal.cli.main import run``).
    """
    if not _installed and os.path.basename(sys.argv[0] if sys.argv else "") == "robocal":
        install_startup_handlers()


def run() -> None:
    """The console script and ``python -m robocal``: handlers first, then the command line; exits."""
    _received.clear()
    install_startup_handlers()
    from .main import main  # the slow part: typer, rich, numpy and every command

    run_command(main)


def run_command(main: Callable[[], int]) -> None:
    """Run ``main`` with the command handlers and exit with its code (or ``128 + signum`` if a signal escapes).

    Args:
        main: :func:`robocal.cli.main.main`.
    """
    install_command_handlers()
    code: int | None = None
    try:
        code = main()
        _block_signals_until_exit()
    except KeyboardInterrupt as exc:
        if code is None:  # it escaped main's own handlers (e.g. a second signal there)
            quiet_after_interrupt()
            signum = getattr(exc, "signum", None) or first_signal() or int(signal.SIGINT)
            try:
                os.write(2, f"error: {interrupted_text(signum)}\n".encode())
            finally:
                os._exit(exit_code_for(signum))
        # the command had finished (its files written, its lines printed) when the signal came, before the
        # handlers were blocked: ignored like one a moment later (it used to escape as a KeyboardInterrupt
        # traceback, the process killed by SIGINT: the rare exit -2 of tests/faults/test_sweep_interrupts.py)
        _block_signals_until_exit()
    if _received or code in _SIGNAL_EXITS:
        _exit_interrupted(code)
    sys.exit(code)


_SIGNAL_EXITS = frozenset(128 + s for s in HANDLED_SIGNALS)


def _exit_interrupted(code: int) -> NoReturn:
    """End an interrupted command with ``code`` (its output flushed), without the interpreter's shutdown.

    CPython keeps a note when a ``KeyboardInterrupt`` leaves some of its own evaluations and, if the note is still
    set as ``python -m`` ends, kills the process by SIGINT (exit -2) instead of returning the exit code, even when
    robocal caught the interruption, made the motors limp and printed its one line (the soaks' rare exit -2 after
    ``error: interrupted``; 4 of 250 Ctrl-Cs at random instants of ``python -m robocal check --help``). The
    command's files are written and closed by now; what is left of the shutdown is freeing memory.
    """
    import contextlib

    for stream in (sys.stdout, sys.stderr):
        with contextlib.suppress(OSError, ValueError, AttributeError):  # a closed pipe: nothing more to say there
            stream.flush()
    logging = sys.modules.get("logging")
    if logging is not None:
        with contextlib.suppress(Exception):  # a handler failing to flush must not change the exit code
            logging.shutdown()
    os._exit(code)


def _block_signals_until_exit() -> None:
    """The command is done: from now on a signal is ignored; the process exits with the command's code.

    Python puts the default handler back while it shuts down (SIG_DFL for a Python handler, not for SIG_IGN), and
    another thread may take the signal, so a Ctrl-C landing then would end the process as killed by SIGINT after
    everything was written and printed. Ignoring is process-wide and survives the shutdown.
    """
    if not _installed:
        return
    for _attempt in range(len(HANDLED_SIGNALS) + 1):  # a signal that lands while they are set is ignored too
        try:
            for signum in HANDLED_SIGNALS:
                try:
                    signal.signal(signum, signal.SIG_IGN)
                except (OSError, ValueError):
                    continue
            return
        except KeyboardInterrupt:
            continue
