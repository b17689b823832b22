"""A running hard-stop sweep: the source read into a wrap-aware range tracker, and the guided direction check.

Samples are read in the identity frame (``s = direction·raw``, what the robot publishes with an empty calibration
file); :class:`SweepSession` keeps the wrap-aware range, the exact extremes and the first readings, and turns them
into a :class:`~robocal.core.sweep.SweepResult`.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Mapping, Sequence
from typing import Protocol

import numpy as np

from ...backends.sources import JointSpec, Source, SourceSpec, check_replay_frame, parse_source
from ...core.arrays import FloatArray
from ...core.sweep import RangeTracker, analyse_sweep, direction_from_motion
from ...core.sweep_result import DEFAULT_SPAN_TOLERANCE_RAD, DEFAULT_THRESHOLD_RAD, SweepResult
from ...errors import UsageError

__all__ = [
    "DEFAULT_DIRECTION_STEP_S",
    "HardStopSweepView",
    "SweepSession",
    "check_source_options",
    "run_direction_check",
]



def check_source_options(source: str, frame: str | None = None) -> SourceSpec:
    """Validate ``--source`` and ``--frame`` (before anything is read or printed).

    Raises:
        UsageError: Malformed source string or unknown frame.
    """
    check_replay_frame(frame)
    return parse_source(source)


def _identity(frame: str, direction: FloatArray, positions: FloatArray) -> FloatArray:
    """Positions in ``frame`` → identity frame ``direction·raw`` (the map is its own inverse), ``(..., N)``."""
    if frame == "motor":
        out: FloatArray = positions * direction
        return out
    return positions


class HardStopSweepView(Protocol):
    """The live view of a hard-stop sweep: what the sweep loop reports to (the CLI's live table, a recorder)."""

    def update(self, session: SweepSession) -> None:
        """Called after every sample (rate-limit the drawing yourself)."""
        ...

    def prompt(self, joint: str) -> None:
        """The direction check asks the operator to move ``joint`` toward its + limit."""
        ...

    def direction_result(self, joint: str, verdict: int) -> None:
        """The direction check's verdict for ``joint``: +1 right, −1 flipped, 0 not verified (no motion)."""
        ...

    def finish(self, result: SweepResult) -> None:
        """Called once with the final result, before anything is written."""
        ...


class SweepSession:
    """The state of a running sweep: a wrap-aware range tracker over the identity frame.

    Besides the wrap-aware range, the session keeps the extremes exactly as read (the one-sided rule of a
    robot whose reading does not wrap uses them, as upstream does) and each joint's first reading.

    Args:
        source: Where samples come from.
        joints: Joints in URDF order (the source's order).
        method: ``two-sided`` or ``one-sided`` (shown by the live view).
        stops: Per joint, the stop of the one-sided procedure as ``(side, angle_rad)``, or None.
        wraps: Whether the position reading wraps each motor turn.
    """

    def __init__(
        self,
        source: Source,
        joints: Sequence[JointSpec],
        *,
        method: str = "two-sided",
        stops: Sequence[tuple[str, float] | None] | None = None,
        wraps: bool = True,
    ) -> None:
        self.source = source
        self.joints = tuple(joints)
        self.names = tuple(j.name for j in self.joints)
        self.direction = np.array([j.direction for j in self.joints], dtype=np.float64)
        self.lower = np.array([j.lower for j in self.joints], dtype=np.float64)
        self.upper = np.array([j.upper for j in self.joints], dtype=np.float64)
        self.tracker = RangeTracker(len(self.joints))
        self.samples = 0
        self.t_s = 0.0
        self.method = method
        self.stops: tuple[tuple[str, float] | None, ...] = (
            tuple(stops) if stops is not None else (None,) * len(self.joints)
        )
        self.wraps = wraps
        n = len(self.joints)
        self._exact_min = np.full(n, np.inf)
        self._exact_max = np.full(n, -np.inf)
        self._first = np.full(n, np.nan)

    def _observe(self, s: FloatArray) -> None:
        """Exact extremes and first readings of a block ``(T, N)`` of identity-frame samples (NaN skipped)."""
        if s.shape[0] == 0:
            return
        np.fmin(self._exact_min, np.fmin.reduce(s, axis=0), out=self._exact_min)
        np.fmax(self._exact_max, np.fmax.reduce(s, axis=0), out=self._exact_max)
        todo = np.isnan(self._first)
        if todo.any():
            finite = np.isfinite(s)
            row = np.argmax(finite, axis=0)
            val = s[row, np.arange(s.shape[1])]
            take = todo & finite.any(axis=0)
            self._first[take] = val[take]

    @property
    def first(self) -> FloatArray:
        """First finite identity-frame reading per joint, shape ``(N,)``, rad (NaN before one)."""
        return np.array(self._first, dtype=np.float64)  # a copy

    @property
    def exact_minimum(self) -> FloatArray:
        """Minimum of the readings exactly as read (no unwrapping), shape ``(N,)``, rad (NaN before one)."""
        return np.where(np.isfinite(self._exact_min), self._exact_min, np.nan)

    @property
    def exact_maximum(self) -> FloatArray:
        """Maximum of the readings exactly as read (no unwrapping), shape ``(N,)``, rad (NaN before one)."""
        return np.where(np.isfinite(self._exact_max), self._exact_max, np.nan)

    def to_identity(self, positions: FloatArray) -> FloatArray:
        """Source frame → identity frame ``direction·raw``, shape ``(..., N)``."""
        return _identity(self.source.frame, self.direction, positions)

    @property
    def exhausted(self) -> bool:
        """True when the source has nothing more."""
        return self.source.exhausted

    @property
    def missing(self) -> dict[str, int]:
        """Joint → samples that had no position for it (NaN, e.g. in a JointState), skipped; only joints with some."""
        gaps = self.samples - self.tracker.count
        return {n: int(g) for n, g in zip(self.names, gaps, strict=True) if g > 0}

    def step(self) -> bool:
        """Read one sample (a replay: a block) into the tracker; False when the source is exhausted."""
        read_block = getattr(self.source, "read_block", None)
        if read_block is not None:  # a replay: blocks of rows, memory bounded by the block
            t, pos = read_block(2000)
            if len(t) == 0:
                return False
            block = self.to_identity(pos)
            self.tracker.update_many(block)
            self._observe(block)
            self.samples += len(t)
            self.t_s = float(t[-1])
            return True
        sample = self.source.read()
        if sample is None:
            return False
        s = self.to_identity(sample.position_rad)
        self.tracker.update(s)
        self._observe(s[None, :])
        self.samples += 1
        self.t_s = sample.t_s
        return True

    def result(
        self,
        *,
        prior: Mapping[str, float] | None = None,
        threshold_rad: float = DEFAULT_THRESHOLD_RAD,
        span_tolerance_rad: float = DEFAULT_SPAN_TOLERANCE_RAD,
        zero_sta: Mapping[str, int] | None = None,
        direction_check: Mapping[str, int] | None = None,
    ) -> SweepResult:
        """Bisection and diagnostics for what was sampled so far."""
        zs = np.array([(zero_sta or {}).get(n, 0) for n in self.names])
        exact = not self.wraps  # a reading that does not wrap: the extremes exactly as read (as upstream)
        return analyse_sweep(
            self.names,
            self.direction,
            self.lower,
            self.upper,
            self.exact_minimum if exact else self.tracker.minimum,
            self.exact_maximum if exact else self.tracker.maximum,
            prior=prior,
            threshold_rad=threshold_rad,
            span_tolerance_rad=span_tolerance_rad,
            zero_sta=zs,
            direction_check=direction_check,
            method=self.method,
            stops=[None if x is None else x[0] for x in self.stops],
            stop_rad=[math.nan if x is None else x[1] for x in self.stops],
            first=self.first,
            wraps=self.wraps,
        )


DEFAULT_DIRECTION_STEP_S = 5.0
"""Time the guided direction check waits per joint for the motion, s (source clock)."""


def run_direction_check(
    source: Source,
    joints: Sequence[JointSpec],
    *,
    on_prompt: Callable[[str], None] | None = None,
    on_result: Callable[[str, int], None] | None = None,
    min_motion_rad: float = 0.1,
    step_s: float = DEFAULT_DIRECTION_STEP_S,
    timeout_s: float = 60.0,
) -> dict[str, int]:
    """Guided direction check: per joint, ask for a move toward the + limit and watch the sign of motion.

    The wait per joint is measured on the source's clock (sample time stamps: wall-clock time on a live bus,
    simulated time on ``sim:``), so a live bus gets ``step_s`` seconds per joint whatever its poll rate;
    ``timeout_s`` of wall-clock time is a guard for a source whose clock stops.

    Args:
        source: A live or simulated source.
        joints: Joints in the source's order.
        on_prompt: Shows the instruction (called before the source is told).
        on_result: Called with each joint's verdict as soon as it is known (+1, −1 or 0: not verified).
        min_motion_rad: Motion that counts, rad.
        step_s: Time to wait at most per joint, s, on the source's clock.
        timeout_s: Wall-clock time to wait at most per joint, s.

    Returns:
        Joint → +1 (URDF direction right), −1 (flipped) or 0 (the joint did not move enough within
        ``step_s``: its direction is not verified).
    """
    if not (math.isfinite(step_s) and step_s > 0):
        raise UsageError(f"direction check time {step_s}: expected a finite number of seconds > 0")
    d = np.array([j.direction for j in joints], dtype=np.float64)
    out: dict[str, int] = {}
    for i, j in enumerate(joints):
        if on_prompt is not None:
            on_prompt(j.name)
        first = source.read()
        source.prompt_positive(j.name)
        verdict = 0
        if first is not None:
            start = float(_identity(source.frame, d, first.position_rad)[i])
            tracker = RangeTracker(1)
            tracker.update([start])
            t_end = first.t_s + step_s
            deadline = time.monotonic() + timeout_s
            while True:
                s = source.read()
                if s is None or s.t_s > t_end or time.monotonic() > deadline:
                    break
                tracker.update([float(_identity(source.frame, d, s.position_rad)[i])])
                start = start if math.isfinite(start) else float(tracker.current[0])
                verdict = direction_from_motion(float(tracker.current[0]) - start, min_motion_rad)
                if verdict:
                    break
        out[j.name] = verdict
        if on_result is not None:
            on_result(j.name, verdict)
    return out
