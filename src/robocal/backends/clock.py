"""Where a joint driver or a simulator takes its time from: the wall clock on hardware, a simulated clock else."""

from __future__ import annotations

import time
from typing import Any, Protocol

__all__ = ["Clock", "MonotonicClock"]


class Clock(Protocol):
    """Where a driver takes its time from (wall clock on hardware, a simulated clock in a simulator)."""

    def now(self) -> float:
        """Seconds (monotonic)."""
        ...

    def sleep(self, dt_s: float) -> Any:
        """Let ``dt_s`` seconds pass."""
        ...


class MonotonicClock:
    """The wall clock (``time.monotonic``/``time.sleep``), for real hardware."""

    def now(self) -> float:
        """Seconds since an arbitrary origin."""
        return time.monotonic()

    def sleep(self, dt_s: float) -> None:
        """Sleep ``dt_s`` seconds (no-op for ≤ 0)."""
        if dt_s > 0:
            time.sleep(dt_s)
