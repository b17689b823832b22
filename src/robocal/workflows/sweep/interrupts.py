"""Ctrl-C and other signals while a hand sweep finishes: which ones interrupt it, and how to name the cause."""

from __future__ import annotations

import contextlib
import signal
import threading
from collections.abc import Iterator
from types import FrameType

from ...errors import SignalInterrupt

__all__ = ["FinishingCtrlC", "signal_name"]


class FinishingCtrlC:
    """Ctrl-C while the sweep finishes (results, prompt, files), counted from the sweep's start.

    The first Ctrl-C asks the sweep to finish and write; when it arrives after the sweep already ended by itself
    (Enter, the source ran out) it is taken as that request and does not interrupt the writing. A second one
    aborts (``KeyboardInterrupt``), and so does one at the prompt (the user declines). Only in the main thread
    (signal handlers live there); SIGTERM and SIGHUP are not touched.
    """

    def __init__(self, seen: int) -> None:
        """Args: seen: Ctrl-Cs already received while sampling (0 or 1)."""
        self.seen = seen
        self._prompt = False
        self._previous: object = None
        self._active = False
        self._raised = False

    def _handler(self, signum: int, frame: FrameType | None) -> None:
        self.seen += 1
        if self.seen >= 2 or self._prompt:
            self._raised = True
            raise KeyboardInterrupt

    def __enter__(self) -> FinishingCtrlC:
        if threading.current_thread() is threading.main_thread():
            previous = signal.getsignal(signal.SIGINT)
            if previous not in (signal.SIG_IGN, None):
                self._previous = previous
                signal.signal(signal.SIGINT, self._handler)
                self._active = True
        return self

    def __exit__(self, *exc: object) -> None:
        if self._active:
            signal.signal(signal.SIGINT, self._previous)  # type: ignore[arg-type]
            self._active = False

    @contextlib.contextmanager
    def at_prompt(self) -> Iterator[None]:
        """Ctrl-C at the prompt declines: it aborts even as the first."""
        self._prompt = True
        try:
            yield
        finally:
            self._prompt = False

    def cause(self, exc: KeyboardInterrupt) -> str:
        """What ended the finishing: ``SIGTERM``, ``a second Ctrl-C`` or ``Ctrl-C`` (at the prompt).

        A ``KeyboardInterrupt`` this handler did not raise (another thread's handler, code raising it) counts as
        one more Ctrl-C.
        """
        if isinstance(exc, SignalInterrupt):
            return signal_name(exc.signum)
        count = self.seen if self._raised else self.seen + 1
        return "a second Ctrl-C" if count >= 2 else "Ctrl-C"


def signal_name(signum: int) -> str:
    """``SIGTERM`` for 15."""
    try:
        return signal.Signals(signum).name
    except ValueError:
        return f"signal {signum}"
