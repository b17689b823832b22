"""Feeds: threads that read a joint source and push its newest frame to a :class:`~robocal.viewer.app.ViewerApp`.

Every feed runs on its own thread at the source's pace and calls :meth:`ViewerApp.push`, which keeps only the
newest frame. A feed that fails (a bus that stops answering, a recording that is malformed further on) shows
the error on the page, records it in :attr:`Feed.error` and stops; the page keeps serving the last pose.

* :class:`SourceFeed` — a robocal :class:`~robocal.backends.sources.Source` (``sim:lite``, ``can:…``), paced by
  the source's time stamps (the simulated Lite) or as fast as the bus answers.
* :class:`ReplayFeed` — a whole recording in memory with play / pause / seek (the page's time slider).
* :class:`CallableFeed` — ``fn(t_s) -> raw`` at a fixed rate (tests, benchmarks, demos).
* :class:`PollFeed` — ``poll() -> raw`` as fast as it answers (LeRobot servo buses, a UR controller).
"""

from __future__ import annotations

import math
import threading
import time
from collections.abc import Callable, Sequence
from typing import Any

import numpy as np
import numpy.typing as npt

from ..backends.bus_transaction import start_signal_free
from ..core.arrays import FloatArray
from ..errors import CalibError, UsageError
from .app import ReplayControl, ViewerApp
from .scene import stop_thread

__all__ = ["CallableFeed", "Feed", "PollFeed", "ReplayFeed", "SourceFeed"]



class Feed:
    """Base of the feeds: a daemon thread, a stop flag, error reporting to the page.

    Args:
        app: Where frames go.
        name: Shown in messages (``sim:lite``, the recording's name, …).
    """

    def __init__(self, app: ViewerApp, name: str) -> None:
        self.app = app
        self.name = name
        self.error: CalibError | None = None
        """The error that stopped the feed, if any (unexpected exceptions are wrapped in a DeviceError)."""
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None

    def start(self) -> Feed:
        """Start the thread."""
        thread = threading.Thread(target=self._main, name=f"robocal-view-feed-{self.name}", daemon=True)
        self._thread = start_signal_free(thread)  # signals go to the main thread, which makes the motors limp
        return self

    def stop(self) -> None:
        """Ask the thread to stop and wait for it (bounded), then release the source."""
        stop_thread(self._stop, self._thread)
        self.close()

    def close(self) -> None:
        """Release what the feed holds (override)."""

    @property
    def alive(self) -> bool:
        """True while the thread runs."""
        return self._thread is not None and self._thread.is_alive()

    def _main(self) -> None:
        self.app.set_source_state("running")
        try:
            self.run()
        except CalibError as exc:
            self._fail(exc)
        except Exception as exc:  # a bug or an unexpected library error: still a message, never a dead page
            from ..errors import DeviceError

            self._fail(DeviceError(f"{type(exc).__name__}: {exc}"))
        else:
            if not self._stop.is_set():
                self.app.set_source_state("finished", f"{self.name}: end of the source")

    def _fail(self, exc: CalibError) -> None:
        self.error = exc
        self.app.set_source_state("failed", f"source {self.name} stopped: {exc}")

    def run(self) -> None:
        """Push frames until the source ends or :meth:`stop` (override)."""
        raise NotImplementedError


class SourceFeed(Feed):
    """A robocal joint source, mapped to the viewer's joints.

    Args:
        app: Where frames go.
        source: An open source (closed by :meth:`stop`).
        name: Shown in messages.
        to_raw: ``(source positions (M,)) -> raw (N,)`` in the viewer's joint order (frame conversion and
            reordering).
        paced: Sleep so that source time runs with the wall clock (a simulator, which computes ahead).
        keep_moving: Called when the source is exhausted; returns True when it restarted (the simulated
            operator sweeps again), False to end.
    """

    def __init__(
        self,
        app: ViewerApp,
        source: Any,
        name: str,
        to_raw: Callable[[FloatArray], FloatArray],
        *,
        paced: bool = False,
        keep_moving: Callable[[], bool] | None = None,
    ) -> None:
        super().__init__(app, name)
        self.source = source
        self.to_raw = to_raw
        self.paced = paced
        self.keep_moving = keep_moving
        self._closed = False

    def run(self) -> None:
        """Read, map, push; pace a simulator to the wall clock."""
        wall0: float | None = None
        t0 = 0.0
        while not self._stop.is_set():
            if self.source.exhausted and not (self.keep_moving is not None and self.keep_moving()):
                return
            sample = self.source.read()
            if sample is None:
                continue
            self.app.push(sample.t_s, self.to_raw(sample.position_rad))
            if self.paced:
                if wall0 is None:
                    wall0, t0 = time.monotonic(), sample.t_s
                ahead = (sample.t_s - t0) - (time.monotonic() - wall0)
                if ahead > 0:
                    self._stop.wait(ahead)

    def close(self) -> None:
        """Close the source once."""
        if not self._closed:
            self._closed = True
            self.source.close()


class CallableFeed(Feed):
    """``fn(t_s) -> raw (N,)`` pushed at ``rate_hz`` (wall clock; time starts at 0).

    Args:
        app: Where frames go.
        fn: The frame at time ``t_s``.
        rate_hz: Frames per second (1000 for the 1 kHz benchmark).
        duration_s: Stop after this long (None: until :meth:`stop`).
        name: Shown in messages.
    """

    def __init__(
        self,
        app: ViewerApp,
        fn: Callable[[float], npt.ArrayLike],
        rate_hz: float,
        *,
        duration_s: float | None = None,
        name: str = "generated",
    ) -> None:
        super().__init__(app, name)
        if not (math.isfinite(rate_hz) and rate_hz > 0):
            raise UsageError(f"feed rate {rate_hz}: expected a positive number of frames per second")
        self.fn = fn
        self.period_s = 1.0 / rate_hz
        self.duration_s = duration_s
        self.pushed = 0

    def run(self) -> None:
        """Push ``fn(t)`` on a fixed schedule; a late schedule skips ahead instead of bursting."""
        start = time.monotonic()
        k = 0
        while not self._stop.is_set():
            t = k * self.period_s
            if self.duration_s is not None and t > self.duration_s:
                return
            self.app.push(t, self.fn(t))
            self.pushed += 1
            k += 1
            delay = start + k * self.period_s - time.monotonic()
            if delay > 0:
                self._stop.wait(delay)
            elif delay < -0.1:  # more than 100 ms behind: skip the missed frames
                k = int((time.monotonic() - start) / self.period_s)


class PollFeed(Feed):
    """``poll() -> raw (N,)`` as fast as it answers, at most ``max_rate_hz``.

    Args:
        app: Where frames go.
        poll: One reading in the viewer's joint order (raises a CalibError when the device fails).
        name: Shown in messages.
        max_rate_hz: Upper bound of the polling rate.
        on_close: Called once by :meth:`stop` (close the bus).
    """

    def __init__(
        self,
        app: ViewerApp,
        poll: Callable[[], npt.ArrayLike],
        name: str,
        *,
        max_rate_hz: float = 200.0,
        on_close: Callable[[], None] | None = None,
    ) -> None:
        super().__init__(app, name)
        self.poll = poll
        self.min_period_s = 1.0 / max_rate_hz
        self.on_close = on_close

    def run(self) -> None:
        """Poll and push until stopped."""
        t0 = time.monotonic()
        while not self._stop.is_set():
            t = time.monotonic()
            self.app.push(t - t0, self.poll())
            delay = t + self.min_period_s - time.monotonic()
            if delay > 0:
                self._stop.wait(delay)

    def close(self) -> None:
        """Run ``on_close`` once."""
        if self.on_close is not None:
            close, self.on_close = self.on_close, None
            close()


class ReplayFeed(Feed, ReplayControl):
    """A recording in memory, played against the wall clock, with play / pause / seek.

    Args:
        app: Where frames go (the page's slider is attached to this feed).
        t_s: Shape ``(T,)``, s, non-decreasing.
        raw: Shape ``(T, N)`` in the viewer's joint order.
        name: Shown in messages.
        speed: Recording seconds per wall second.
        autoplay: Start playing at once.
        clock: Monotonic clock (tests inject one).
    """

    def __init__(
        self,
        app: ViewerApp,
        t_s: FloatArray,
        raw: FloatArray,
        name: str,
        *,
        speed: float = 1.0,
        autoplay: bool = True,
        clock: Callable[[], float] = time.monotonic,
    ) -> None:
        super().__init__(app, name)
        if len(t_s) == 0:
            raise UsageError(f"recording {name}: no samples to play")
        if not (math.isfinite(speed) and speed > 0):
            raise UsageError(f"--speed {speed}: expected a positive number")
        self.t_s = np.asarray(t_s, dtype=np.float64)
        self.raw = np.asarray(raw, dtype=np.float64)
        self.t_start_s = float(self.t_s[0])
        self.t_end_s = float(self.t_s[-1])
        self.speed = speed
        self.clock = clock
        self._lock = threading.Lock()
        self._playing = autoplay
        self._pos = self.t_start_s
        self._wall_ref = clock()
        self._pos_ref = self.t_start_s
        self._shown = -1
        self._wake = threading.Event()

    @property
    def playing(self) -> bool:
        """True while playing."""
        return self._playing

    @property
    def position_s(self) -> float:
        """Current recording time, s."""
        with self._lock:
            return self._now()

    def _now(self) -> float:
        if self._playing:
            self._pos = min(self.t_end_s, self._pos_ref + (self.clock() - self._wall_ref) * self.speed)
            if self._pos >= self.t_end_s:
                self._playing = False
        return self._pos

    def play(self) -> None:
        """Play from the current position (from the start again at the end)."""
        with self._lock:
            pos = self._now()
            if pos >= self.t_end_s:
                pos = self.t_start_s
            self._pos = self._pos_ref = pos
            self._wall_ref = self.clock()
            self._playing = True
        self._wake.set()

    def pause(self) -> None:
        """Stop at the current position."""
        with self._lock:
            self._now()
            self._playing = False
        self._wake.set()

    def seek(self, t_s: float) -> None:
        """Jump to ``t_s`` (clamped) and show its frame at once."""
        if not math.isfinite(t_s):
            raise UsageError(f"seek to {t_s}: expected a finite time")
        with self._lock:
            pos = min(max(t_s, self.t_start_s), self.t_end_s)
            self._pos = self._pos_ref = pos
            self._wall_ref = self.clock()
        self.push_current()
        self._wake.set()

    def index_at(self, t_s: float) -> int:
        """Row shown at recording time ``t_s``: the last sample at or before it."""
        return max(0, int(np.searchsorted(self.t_s, t_s, side="right")) - 1)

    def push_current(self) -> None:
        """Push the row at the current position (if it differs from the last one pushed)."""
        i = self.index_at(self.position_s)
        if i != self._shown:
            self._shown = i
            self.app.push(float(self.t_s[i]), self.raw[i])

    def run(self) -> None:
        """Push the row under the play head at up to 200 Hz; idle while paused (the page stays live)."""
        self.push_current()
        while not self._stop.is_set():
            self.push_current()
            self._wake.wait(0.005 if self._playing else 0.1)
            self._wake.clear()


def reorder(source_names: Sequence[str], viewer_names: Sequence[str]) -> npt.NDArray[np.intp]:
    """Index array: ``raw_viewer = positions_source[idx]`` (``-1`` where the source lacks the joint)."""
    where = {n: i for i, n in enumerate(source_names)}
    return np.array([where.get(n, -1) for n in viewer_names], dtype=np.intp)
