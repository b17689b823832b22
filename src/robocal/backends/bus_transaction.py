"""Bus transactions that a signal cannot cut in half.

A signal handler that raises (Ctrl-C's ``KeyboardInterrupt``, or the exceptions
:class:`robocal.workflows.motion.guard.MotionGuard` raises for SIGTERM, SIGHUP and SIGQUIT) may fire between any two
byte codes. Inside a vendor SDK call that leaves the port half used: scservo_sdk and dynamixel_sdk set
``PortHandler.is_using`` before a packet goes out and clear it only after its reply was read, so an exception in
between makes every later packet fail with "port is in use" — including the writes that would turn the motors'
torque off. A bus runs each packet exchange inside :func:`transaction`; a guard's signal handler calls
:func:`raise_now_or_after` instead of raising, and the exception comes out as soon as the exchange is complete
(at most one packet timeout later), with the port in a clean state.

Signals go to the main thread: a helper thread robocal starts while motors move (the keep-alive of the CAN
motors, a viewer) is started by :func:`start_signal_free` with :data:`HANDLED_SIGNALS` blocked in it. Otherwise
the kernel may deliver a process-directed signal to that thread; Python then runs the handler only when the main
thread next runs byte code, which a main thread blocked in a reply wait does only once the wait ends (up to the
reply timeout later).

Module state: the nesting depth of the exchange running on the main thread (signal handlers run there) and the
one exception held back. Other threads' exchanges are not counted.
"""

from __future__ import annotations

import contextlib
import signal
import threading
from collections.abc import Iterator

__all__ = [
    "HANDLED_SIGNALS",
    "holding",
    "in_transaction",
    "raise_now_or_after",
    "signals_held",
    "start_signal_free",
    "transaction",
]

HANDLED_SIGNALS: tuple[signal.Signals, ...] = tuple(
    getattr(signal, n) for n in ("SIGINT", "SIGTERM", "SIGHUP", "SIGQUIT") if hasattr(signal, n)
)
"""The signals robocal's handlers turn into a safe ending (Ctrl-C, kill, a closed terminal, Ctrl-\\)."""

_depth = 0
_held: BaseException | None = None


def in_transaction() -> bool:
    """Whether the main thread is inside a packet exchange."""
    return _depth > 0


def holding() -> bool:
    """Whether an exception a signal handler raised is held back until the exchange is complete."""
    return _held is not None


@contextlib.contextmanager
def transaction() -> Iterator[None]:
    """One packet exchange; an exception a signal handler held back is raised when it ends (main thread only)."""
    global _depth, _held
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    _depth += 1
    try:
        yield
    finally:
        _depth -= 1
        if _depth == 0 and _held is not None:
            held, _held = _held, None
            raise held


def raise_now_or_after(exc: BaseException) -> None:
    """Raise ``exc`` now, or, inside a packet exchange, once it is complete (the first one held wins)."""
    global _held
    if _depth > 0:
        if _held is None:
            _held = exc
        return
    raise exc


def start_signal_free(thread: threading.Thread) -> threading.Thread:
    """Start ``thread`` with :data:`HANDLED_SIGNALS` blocked in it (they go to the main thread); returns it.

    The calling thread blocks them around ``thread.start()`` (a new thread inherits the mask), so there is no
    instant at which the new thread could take one; a signal that arrives meanwhile stays pending and is taken
    by the caller once its mask is restored. Where ``pthread_sigmask`` does not exist (Windows) the thread is
    just started (signals there only ever reach the main thread).
    """
    mask = getattr(signal, "pthread_sigmask", None)
    if mask is None:
        thread.start()
        return thread
    old = mask(signal.SIG_BLOCK, HANDLED_SIGNALS)
    try:
        thread.start()
    finally:
        mask(signal.SIG_SETMASK, old)
    return thread


@contextlib.contextmanager
def signals_held() -> Iterator[None]:
    """Hold :data:`HANDLED_SIGNALS` off while the block runs, whatever handler is installed.

    The first one that came is raised again as the block ends, so its handler (or default action) acts then. For what must not be cut short once begun, such as making every motor limp and putting its watchdog back: a
    signal's exception inside would skip the motors after it. Main thread only (where handlers run; elsewhere the
    block just runs); SIGKILL still ends the process.
    """
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    came: list[int] = []
    previous: dict[signal.Signals, object] = {}
    try:  # installed inside: a signal that lands between two installs still gets every handler put back
        for sig in HANDLED_SIGNALS:
            with contextlib.suppress(OSError, ValueError):
                previous[sig] = signal.signal(sig, lambda n, _frame: came.append(n))
        yield
    finally:
        for sig, handler in previous.items():
            with contextlib.suppress(OSError, ValueError, TypeError):
                signal.signal(sig, handler)  # type: ignore[arg-type]
        if came:
            signal.raise_signal(came[0])  # handled now, by the handler it was meant for
