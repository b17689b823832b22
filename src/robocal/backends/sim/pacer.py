"""Real time for a standalone simulated device: its simulated clock kept level with the wall clock.

A standalone ``robocal sim`` (the Lite, the OpenArm) has clients that do not sleep on its clock, so
:class:`RealtimePacer` moves the clock with the wall clock every few milliseconds, integrating every motor's plant
under its last command and applying the motors' host-loss watchdogs on that clock (each motor's ``sync()``).

**The simulator's own stalls do not count as the host's silence.** A real motor's controller never stops; the
simulator's process does, when the machine is busy. Frames the host sent meanwhile wait in the simulator's socket
and are handled when it runs again, too late for a watchdog that judged them by the time it got to them: at load 15
on two cores the OpenArm's 0.5 s TIMEOUT tripped in 5 of 9 undisturbed gripper searches that way (2026-11-29).
When the pacer finds it was itself held up (a gap over :data:`STALL_S` between its turns), that time is taken off
every motor's silence (``last_rx_s`` moves on by it) before the clock catches up. A host silent while the simulator
runs is judged as before, to the tick; a host silent exactly while the simulator was held up trips that much later.
"""

from __future__ import annotations

import threading
import time
from collections.abc import Callable, Iterable
from contextlib import AbstractContextManager
from typing import Any, Protocol

from .physics import SimClock

__all__ = ["PACE_S", "STALL_S", "PacedMotor", "RealtimePacer", "own_stall_s"]

PACE_S = 0.005
"""How often a standalone simulator integrates its joints (s)."""
STALL_S = 0.1
"""A gap between two of the pacer's turns longer than this (s) is the simulator's own stall (20 turns missed)."""


def own_stall_s(gap_s: float, period_s: float = PACE_S) -> float:
    """How long the simulator itself was held up, from the gap between two of its pacer's turns (s).

    Args:
        gap_s: Wall time between the two turns (s).
        period_s: The pacer's period (s).

    Returns:
        ``gap_s - period_s`` when the gap is over :data:`STALL_S`, else 0 (ordinary scheduling jitter).
    """
    return gap_s - period_s if gap_s > STALL_S else 0.0


class PacedMotor(Protocol):
    """A simulated motor the pacer moves: its last frame's time on the clock and a step up to the clock."""

    last_rx_s: float | None

    def sync(self) -> None:
        """Apply the watchdog and integrate the plant up to the clock."""


class RealtimePacer:
    """Moves a :class:`~.physics.SimClock` with the wall clock (never behind it), integrating every motor's plant.

    Args:
        clock: The motors' simulated clock.
        motors: The simulated motors (each with a plant on ``clock``).
        locked: A context manager factory holding off the buses' threads while the joints are integrated.
        period_s: How often (s).
        name: The thread's name.
    """

    def __init__(
        self,
        clock: SimClock,
        motors: Iterable[PacedMotor],
        locked: Callable[[], AbstractContextManager[Any]],
        period_s: float = PACE_S,
        name: str = "sim-pacer",
    ) -> None:
        self.clock, self.motors, self._locked, self.period_s = clock, list(motors), locked, period_s
        self.name = name
        self.stalls_s: list[float] = []
        """How long each of the simulator's own stalls was (s), as taken off the motors' silence."""
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None

    def start(self) -> None:
        """Start pacing (a daemon thread)."""
        self._stop.clear()
        self._thread = threading.Thread(target=self._pace, name=self.name, daemon=True)
        self._thread.start()

    def stop(self) -> None:
        """Stop pacing."""
        self._stop.set()
        if self._thread is not None:
            self._thread.join(timeout=2.0)
            self._thread = None

    def tick(self, wall_elapsed_s: float, sim0_s: float, stalled_s: float = 0.0) -> None:
        """Bring the clock to ``sim0_s + wall_elapsed_s`` and every joint and watchdog up to it.

        Args:
            wall_elapsed_s: Wall time since pacing began (s).
            sim0_s: The clock's time when pacing began (s).
            stalled_s: How long the simulator itself was held up since the last turn (s): taken off every
                motor's silence first.
        """
        with self._locked():
            if stalled_s > 0.0:
                self.stalls_s.append(stalled_s)
                for m in self.motors:
                    if m.last_rx_s is not None:
                        m.last_rx_s += stalled_s
            behind = sim0_s + wall_elapsed_s - self.clock.now()
            if behind > 0:
                self.clock.advance(behind)
            for m in self.motors:
                m.sync()

    def _pace(self) -> None:
        wall0, sim0 = time.monotonic(), self.clock.now()
        last = wall0
        while not self._stop.wait(self.period_s):
            now = time.monotonic()
            gap, last = now - last, now
            self.tick(now - wall0, sim0, own_stall_s(gap, self.period_s))
