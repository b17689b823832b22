"""What every python-can bus of robocal shares (Robstride, Damiao): opening within a deadline, and the reply wait.

Opening (:func:`open_within`): python-can's socketcand client waits for the server's greeting without a timeout, so
a server that accepts and then says nothing (a frozen process) would hang the command forever; the channel is
opened in a worker thread and given up after a deadline (a device error, exit 3).

The reply wait (:func:`frames_until`): a reply that arrived before the deadline while this process was descheduled
is still a reply in time: once the deadline has passed, the frames already queued are taken without waiting (at
most :data:`LATE_FRAMES`), then the wait ends.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Iterator
from typing import Any, TypeVar

from ..errors import CalibTimeoutError, DeviceError

__all__ = ["LATE_FRAMES", "OPEN_DEADLINE_S", "READ_TRIES", "asked_again", "frames_until", "open_within"]

_T = TypeVar("_T")

OPEN_DEADLINE_S = 15.0
"""Opening a CAN channel gives up after this (plus the reply timeout): python-can itself retries a refused
socketcand connection for up to 10 s."""

LATE_FRAMES = 1024
"""At most this many frames already queued are taken once a deadline has passed."""


def frames_until(
    bus: Any, deadline: float, *, extended: bool, now: Callable[[], float] = time.monotonic
) -> Iterator[Any]:
    """The python-can messages ``bus`` receives before ``deadline`` (``time.monotonic``), late ones too.

    Those already queued when the deadline passed are taken without waiting; only extended-id frames
    (``extended``) or only standard-id ones are yielded. ``now``: the clock ``deadline`` is on (the caller's
    ``time.monotonic``).
    """
    late = 0
    while True:
        remaining = deadline - now()
        if remaining <= 0:
            late += 1
            if late > LATE_FRAMES:
                return
        msg = bus.recv(timeout=max(remaining, 0.0))
        if msg is None:
            return
        if bool(msg.is_extended_id) == extended:
            yield msg


def open_within(deadline_s: float, open_fn: Callable[[], Any], what: str) -> Any:
    """``open_fn()`` in a worker thread, or :class:`DeviceError` when it neither returns nor raises in time.

    A client stuck in its handshake is left behind in its (daemon) thread, which takes no signal (they stay with
    the main thread); the command ends with exit 3.

    Raises:
        DeviceError: ``open_fn`` raised (``cannot open WHAT: ...``) or did not return within ``deadline_s``.
    """
    import threading

    from .bus_transaction import start_signal_free

    box: list[Any] = []

    def run() -> None:
        try:
            box.append(("ok", open_fn()))
        except Exception as exc:  # python-can raises CanError / OSError / ValueError by interface
            box.append(("error", exc))

    worker = start_signal_free(threading.Thread(target=run, name=f"open {what}", daemon=True))
    worker.join(deadline_s)
    if not box:
        raise DeviceError(f"cannot open {what}: no answer within {deadline_s:g} s (the device or server is frozen)")
    kind, value = box[0]
    if kind == "error":
        raise DeviceError(f"cannot open {what}: {value}") from None
    return value


READ_TRIES = 3
"""A read (it changes nothing) is asked this many times before a device that did not answer is named."""


def asked_again(read: Callable[[], _T], tries: int = READ_TRIES) -> _T:
    """``read()``, asked again up to ``tries`` times in all while it raises :class:`CalibTimeoutError`.

    For requests that change nothing (a register read): on a busy host one reply can come later than the wait
    (python-can's queue, a simulator or a bus adapter descheduled), and the Damiao fault soaks of 2026-11-29 lost
    runs at connect to "no reply within 0.1 s" from all eight motors with no fault injected. A device that stays
    silent is still named, ``tries`` reply waits later (the last attempt's error is raised).
    """
    for _ in range(tries - 1):
        try:
            return read()
        except CalibTimeoutError:
            continue
    return read()
