"""A one-frame mailbox between a fast joint source and the page: the newest frame wins, nothing queues.

A source thread calls :meth:`LatestFrame.put` at its own rate (1 kHz for a servo bus); the page loop calls
:meth:`LatestFrame.take` at the page rate (20–30 Hz) and gets only the newest frame. Every frame that was
replaced before it was taken counts as dropped. The time a frame waited is measured with the injected clock,
so tests can prove the wait stays below one page period however fast the source is.
"""

from __future__ import annotations

import threading
import time
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from ..core.arrays import FloatArray

__all__ = ["Frame", "LatestFrame", "next_tick"]



@dataclass(frozen=True)
class Frame:
    """One reading of every shown joint.

    Attributes:
        seq: 1 for the first frame put, then +1 per frame.
        t_s: The source's time stamp, s (recording time for a replay).
        raw: Shape ``(N,)``, raw joint values in the viewer's joint order (NaN: no reading).
        put_s: Clock time when it was put, s.
    """

    seq: int
    t_s: float
    raw: FloatArray
    put_s: float


class LatestFrame:
    """Thread-safe newest-frame slot.

    Args:
        clock: Monotonic clock in s (injected by tests).
    """

    def __init__(self, clock: Callable[[], float] = time.monotonic) -> None:
        self.clock = clock
        self._lock = threading.Lock()
        self._frame: Frame | None = None
        self._seq = 0
        self._taken_seq = 0
        self.dropped = 0
        """Frames replaced before anyone took them."""

    @property
    def frames_in(self) -> int:
        """Frames put so far."""
        return self._seq

    def put(self, t_s: float, raw: npt.ArrayLike) -> None:
        """Store a frame (copied), replacing an untaken one (counted in :attr:`dropped`)."""
        arr = np.array(raw, dtype=np.float64)
        with self._lock:
            if self._frame is not None and self._frame.seq > self._taken_seq:
                self.dropped += 1
            self._seq += 1
            self._frame = Frame(self._seq, float(t_s), arr, self.clock())

    def take(self) -> Frame | None:
        """The newest frame if it was not taken yet, else None."""
        with self._lock:
            f = self._frame
            if f is None or f.seq <= self._taken_seq:
                return None
            self._taken_seq = f.seq
            return f

    def peek(self) -> Frame | None:
        """The newest frame, taken or not."""
        with self._lock:
            return self._frame


def next_tick(deadline_s: float, now_s: float, period_s: float) -> tuple[float, float]:
    """The page loop's schedule: the next deadline and how long to wait for it (never negative).

    Deadlines stay on the grid ``deadline_s + k·period_s``: a tick that woke a little late (a loaded machine's
    scheduling delay) is followed by one that waits less, so the loop keeps its rate. A loop more than a whole
    period behind starts a new grid at ``now_s`` instead of catching up in a burst.

    Args:
        deadline_s: The deadline of the tick that just ran, s.
        now_s: The time now, s.
        period_s: The page period ``1/rate``, s.

    Returns:
        ``(next deadline, wait)`` in s.
    """
    nxt = deadline_s + period_s
    if nxt < now_s - period_s:  # more than a period behind: skip, never burst
        return now_s, 0.0
    return nxt, max(0.0, nxt - now_s)
