"""Keeping the enabled MIT-mode CAN motors of one run alive, and the watchdog time that goes with the reply wait.

A CAN motor robocal drives (Damiao, issue 31) has a host-loss watchdog armed: a motor that hears no frame for
that long makes itself limp. Several motors of a run are enabled at once (one searched, the others holding a pose
or parked), and every one of them must hear a frame well within its watchdog, also while the searched joint waits
for a slow reply.

* Inline (every clock): after each exchange of a driver, the quiet enabled motors of the run get their last command
  again once :data:`KEEPALIVE_S` has passed since their last frame (the reply is read and judged).
* Independent (the wall clock only, :class:`KeepAliveThread`): a thread that re-sends, without waiting for the
  reply, the last command of every enabled motor whose last frame is older than :data:`THREAD_KEEPALIVE_S` and
  whose driver is not in an exchange of its own; so one exchange that waits for its reply as long as the reply
  timeout allows no longer starves the other motors' watchdogs. It sends only while the host's own loop is alive
  (a driver began a bus call within ``stall_s``): a host that is held up, killed or cut off still lets every
  motor's watchdog act.

:func:`watchdog_for` makes the watchdog/reply-wait relation explicit: the watchdog robocal arms is over twice the
longest reply wait (one lost reply and one slow one in a row never trip it), and a reply wait that would need a
watchdog over :data:`WATCHDOG_MAX_S` is refused before anything moves.
"""

from __future__ import annotations

import contextlib
import math
import threading
import time
from typing import Protocol

from ..errors import UsageError
from . import REPLY_TIMEOUT_ENV
from .bus_transaction import start_signal_free

__all__ = [
    "KEEPALIVE_S",
    "THREAD_KEEPALIVE_S",
    "WATCHDOG_MAX_S",
    "WATCHDOG_MIN_S",
    "KeepAliveThread",
    "KeptAlive",
    "RunPeers",
    "forget",
    "peers_of",
    "watchdog_for",
]

KEEPALIVE_S = 0.1
"""An enabled motor not being commanded gets its last command again (inline, reply judged) after this long."""
THREAD_KEEPALIVE_S = 0.2
"""The independent keep-alive re-sends a motor's last command once its last frame is this old (it then leaves the
inline one, which reads the reply, to do it whenever the host's loop runs normally)."""
_TICK_S = 0.02
_GIVE_UP_S = 30.0
WATCHDOG_MIN_S = 0.5
"""The host-loss watchdog armed when replies are quick: a motor that hears no frame for 0.5 s makes itself limp."""
WATCHDOG_MAX_S = 2.0
"""No watchdog longer than this is armed: a reply wait that would need one is refused."""
_WATCHDOG_MARGIN_S = 0.1


def watchdog_for(reply_wait_s: float) -> float:
    """The watchdog time to arm for a bus whose reply waits last up to ``reply_wait_s``, s.

    ``max(0.5 s, 2·reply_wait + 0.1 s)``, rounded up to 0.05 s: always over twice the reply wait, so that a lost
    reply followed by a slow one does not trip a motor whose host is alive.

    Raises:
        UsageError: The watchdog would have to be longer than :data:`WATCHDOG_MAX_S` (a reply wait of 0.95 s or
            more than 0.95 s, e.g. ``$ROBOCAL_REPLY_TIMEOUT_MS`` over 950).
    """
    if not (math.isfinite(reply_wait_s) and reply_wait_s >= 0):
        raise UsageError(f"reply wait {reply_wait_s!r} s: expected a number of seconds >= 0")
    need = max(WATCHDOG_MIN_S, math.ceil((2.0 * reply_wait_s + _WATCHDOG_MARGIN_S) / 0.05 - 1e-9) * 0.05)
    if need > WATCHDOG_MAX_S + 1e-9 or not need > 2.0 * reply_wait_s:
        raise UsageError(
            f"a reply wait of {reply_wait_s:g} s (${REPLY_TIMEOUT_ENV} or the bus's timeout) needs a host-loss "
            f"watchdog over twice as long ({2.0 * reply_wait_s:g} s), and robocal arms at most {WATCHDOG_MAX_S:g} s "
            f"(a lost host must stop the motors quickly): set {REPLY_TIMEOUT_ENV} to "
            f"{round((WATCHDOG_MAX_S - _WATCHDOG_MARGIN_S) / 2 * 1000)} or less"
        )
    return round(need, 3)


class KeptAlive(Protocol):
    """What the keep-alive needs of a joint driver."""

    lock: threading.RLock
    enabled: bool
    last_tx_s: float
    """When the driver last sent its motor a frame (the clock's seconds)."""
    last_keepalive_s: float
    """When the independent keep-alive last did (``time.monotonic``)."""

    def resend_nowait(self) -> None:
        """Send the motor its last command again without waiting for the reply."""
        ...


class KeepAliveThread:
    """The independent keep-alive of one run's drivers on the wall clock (see the module docstring).

    Args:
        stall_s: Keep-alives stop once no driver began a bus call for this long (the host's loop is stuck).
    """

    def __init__(self, stall_s: float) -> None:
        self.stall_s = float(stall_s)
        self.heartbeat_s = time.monotonic()
        self.sent = 0
        """Keep-alive frames sent (tests)."""
        self._members: list[KeptAlive] = []
        self._stop = threading.Event()
        # the handled signals stay with the main thread (a signal taken here would wait for its reply wait to end)
        self._thread = start_signal_free(threading.Thread(target=self._run, name="robocal-keepalive", daemon=True))

    def beat(self) -> None:
        """The host's loop is alive (a driver begins a bus call)."""
        self.heartbeat_s = time.monotonic()

    def set_members(self, members: list[KeptAlive]) -> None:
        """The enabled drivers of the run (a copy is kept)."""
        self._members = list(members)

    def stop(self) -> None:
        """Stop the thread (returns at once; it ends within one tick)."""
        self._stop.set()

    def alive(self) -> bool:
        """Whether the thread still runs (it ends by :meth:`stop`, or once the host's loop was silent 30 s)."""
        return self._thread.is_alive()

    def _run(self) -> None:
        while not self._stop.wait(_TICK_S):
            now = time.monotonic()
            if now - self.heartbeat_s > max(_GIVE_UP_S, self.stall_s):
                return  # a run abandoned without its limp (an exception the caller kept): nothing to keep alive
            if now - self.heartbeat_s > self.stall_s:
                continue  # the host's own loop has stopped: leave the motors to their watchdogs
            for d in self._members:
                if not d.lock.acquire(blocking=False):
                    continue  # in an exchange of its own (or being made limp)
                try:
                    if d.enabled and now - max(d.last_tx_s, d.last_keepalive_s) >= THREAD_KEEPALIVE_S:
                        d.last_keepalive_s = now
                        with contextlib.suppress(Exception):  # a closed or lost bus: the host's loop sees it
                            d.resend_nowait()
                            self.sent += 1
                finally:
                    d.lock.release()


class RunPeers:
    """The enabled drivers of one run (one clock), and its independent keep-alive when the clock is the wall's."""

    def __init__(self) -> None:
        self.members: list[KeptAlive] = []
        self.thread: KeepAliveThread | None = None

    def beat(self) -> None:
        """A driver begins a bus call (the host's loop is alive)."""
        if self.thread is not None:
            self.thread.beat()

    def add(self, driver: KeptAlive, *, wall_clock: bool, stall_s: float) -> None:
        """``driver`` is enabled (armed); on the wall clock the keep-alive thread starts with the first one."""
        if driver not in self.members:
            self.members.append(driver)
        if wall_clock and (self.thread is None or not self.thread.alive()):
            self.thread = KeepAliveThread(stall_s)
        if self.thread is not None:
            self.thread.stall_s = max(self.thread.stall_s, stall_s)
            self.thread.set_members(self.members)

    def remove(self, driver: KeptAlive) -> bool:
        """``driver`` is limp; True when none is left (the thread is stopped)."""
        if driver in self.members:
            self.members.remove(driver)
        if self.thread is not None:
            self.thread.set_members(self.members)
            if not self.members:
                self.thread.stop()
                self.thread = None
        return not self.members


_RUNS: dict[int, RunPeers] = {}
"""Enabled drivers per clock (the joints of one run)."""


def peers_of(clock: object, *, create: bool = True) -> RunPeers | None:
    """The run of ``clock`` (created on first use unless ``create`` is False)."""
    run = _RUNS.get(id(clock))
    if run is None and create:
        run = _RUNS[id(clock)] = RunPeers()
    return run


def forget(clock: object) -> None:
    """Drop the run of ``clock`` (its last driver went limp)."""
    _RUNS.pop(id(clock), None)
