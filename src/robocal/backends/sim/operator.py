"""A person's hands on a simulated robot, for ``robocal sim``: move a joint, push it into a stop, sweep.

A :class:`HandOperator` moves the joints of a :class:`HandDevice` (a simulated arm or the simulated Lite) in
real time from a background thread, so a client reading positions over the wire sees a hand-speed motion.
Hard stops hold a joint that is pushed past them. A joint whose motor has torque on is held by the motor:
the hand cannot move it (the request is refused, naming the joint).

Positions are in the device's own unit (:attr:`HandDevice.unit`): actual encoder ticks on the servo arms
(continuous across the 0/4096 seam, the frame of the hard stops), radians in the joint frame on the Lite.
"""

from __future__ import annotations

import threading
import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any, Protocol

from ...errors import UsageError

__all__ = ["HandDevice", "HandOperator", "JointView"]


@dataclass(frozen=True)
class JointView:
    """What the live view and the control interface show of one joint.

    Attributes:
        name: Joint name.
        position: Physical position (device unit).
        low: Lower hard stop (device unit).
        high: Upper hard stop (device unit).
        mid: Middle of the range, where the hand holds it for "middle" (device unit).
        torque: Motor torque on (the hand cannot move the joint).
        reading: What the motor reports now (Present_Position ticks, or the motor's angle in rad).
        last_write: The last value a client wrote to this motor, e.g. ``"Goal_Position=2048"``.
        last_write_age_s: Seconds since that write (None: never written).
        extra: Device-specific fields (servo id, baud rate, plugged in; CAN id, enabled).
    """

    name: str
    position: float
    low: float
    high: float
    mid: float
    torque: bool
    reading: float
    last_write: str
    last_write_age_s: float | None
    extra: Mapping[str, Any] = field(default_factory=dict)

    def as_dict(self) -> dict[str, Any]:
        """JSON-ready form (what the control interface's ``state`` returns per joint)."""
        return {
            "name": self.name,
            "position": self.position,
            "low": self.low,
            "high": self.high,
            "mid": self.mid,
            "torque": self.torque,
            "reading": self.reading,
            "last_write": self.last_write,
            "last_write_age_s": self.last_write_age_s,
            **dict(self.extra),
        }


class HandDevice(Protocol):
    """A simulated robot whose joints a hand can move."""

    unit: str
    """``"ticks"`` or ``"rad"``."""
    step: float
    """A sensible small hand step in that unit (the arrow keys)."""
    lock: threading.RLock
    """Guards the device state shared with the wire thread."""

    def joint_names(self) -> Sequence[str]:
        """Joints in display order."""
        ...

    def view(self, name: str) -> JointView:
        """The joint's current state."""
        ...

    def place(self, name: str, position: float) -> None:
        """Put the joint at ``position`` (clamped by the hard stops); the caller holds :attr:`lock`."""
        ...

    def reads(self, name: str) -> int:
        """How many times a client has read the joint's position so far (a paced sweep waits for them)."""
        ...


def _overshoot(dev: HandDevice, v: JointView) -> float:
    return max(dev.step * 2, 0.02 * (v.high - v.low))


PACED_MAX_STEP_S = 0.05
"""A paced sweep's hand advances at most this much along its path per placement (a starved thread never jumps)."""
PACED_OTHER_READS = 64
"""A paced joint stops waiting once the client read other joints this many times but not it (it is not watched)."""
PACED_PATIENCE_S = 10.0
"""A paced joint stops waiting once no joint at all was read for this long (the client went away)."""


@dataclass
class _Motion:
    """One joint's running motion: segments ``(duration_s, from, to)`` and how far along it is.

    Unpaced, ``t_s`` is the wall-clock time since ``start``. Paced, ``t_s`` advances only after the client read
    the previous placement, by at most :data:`PACED_MAX_STEP_S`, and stops at every segment end (each stop is
    placed and read before the hand moves on).
    """

    segments: list[tuple[float, float, float]]
    start: float
    paced: bool = False
    t_s: float = 0.0
    last_tick: float = 0.0
    placed_reads: int | None = None
    """The joint's read count when it was last placed (paced)."""
    placed_total: int = 0
    """Every joint's read count together when it was last placed (paced)."""
    watched: bool = True
    """Paced: the client reads this joint, so the hand waits for each reading."""

    @property
    def duration(self) -> float:
        return sum(d for d, _, _ in self.segments)

    def target(self) -> float:
        """Position at ``t_s`` along the path."""
        t = 0.0
        for dur, a, b in self.segments:
            if self.t_s < t + dur:
                frac = 0.0 if dur <= 0 else max(0.0, (self.t_s - t) / dur)
                return a + (b - a) * frac
            t += dur
        return self.segments[-1][2]

    def advance_paced(self, now: float, reads: int, total: int, last_read: float) -> bool:
        """Move ``t_s`` on if the client saw the last placement (or is not watching this joint); False: wait."""
        if self.placed_reads is not None and reads == self.placed_reads and self.watched:
            if total - self.placed_total >= PACED_OTHER_READS or now - last_read >= PACED_PATIENCE_S:
                self.watched = False  # the client reads other joints but not this one, or nothing any more
            else:
                self.last_tick = now
                return False
        step = min(max(now - self.last_tick, 0.0), PACED_MAX_STEP_S)
        self.last_tick = now
        end = 0.0
        for dur, _, _ in self.segments:  # stop at the next segment end: every waypoint is placed
            end += dur
            if self.t_s < end:
                self.t_s = min(self.t_s + step, end)
                return True
        self.t_s = end
        return True


class HandOperator:
    """Moves the joints of a simulated device as a person would, in real time.

    Args:
        device: The simulated robot.
        rate_hz: How often a running motion updates the joints.
    """

    def __init__(self, device: HandDevice, *, rate_hz: float = 200.0) -> None:
        self.device = device
        self.rate_hz = rate_hz
        self._plans: dict[str, _Motion] = {}
        """joint → its running motion."""
        self._last_read = (0, time.monotonic())
        """Every joint's read count together, and when it last changed."""
        self._cv = threading.Condition()
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, name="sim-hand", daemon=True)
        self._thread.start()
        self.on_change: Callable[[], None] | None = None

    # ------------------------------------------------------------------------------------------ checks
    def _joints(self, joints: str | Sequence[str] | None) -> list[str]:
        names = list(self.device.joint_names())
        if joints is None or joints == "all":
            return names
        wanted = [joints] if isinstance(joints, str) else list(joints)
        unknown = [j for j in wanted if j not in names]
        if unknown:
            raise UsageError(f"unknown joint(s) {', '.join(map(str, unknown))}; joints: {', '.join(names)}")
        return wanted

    def _free(self, names: Sequence[str]) -> None:
        held = [n for n in names if self.device.view(n).torque]
        if held:
            raise UsageError(
                f"torque is on for {', '.join(held)}: the motor holds the joint, the hand cannot move it "
                "(the client must disable torque first)"
            )

    # ----------------------------------------------------------------------------------------- commands
    def move(self, joint: str, *, to: float | None = None, by: float | None = None) -> float:
        """Move one joint to a position or by a step (device unit); returns where it ended (stops hold it)."""
        (name,) = self._joints(joint)
        if (to is None) == (by is None):
            raise UsageError("move: give exactly one of 'to' and 'by'")
        with self.device.lock:
            self._free([name])
            self._cancel([name])
            v = self.device.view(name)
            self.device.place(name, float(to) if to is not None else v.position + float(by or 0.0))
            return self.device.view(name).position

    def push(self, joints: str | Sequence[str] | None, stop: str) -> dict[str, float]:
        """Push joints into their ``"min"`` or ``"max"`` hard stop (and hold them there)."""
        if stop not in ("min", "max"):
            raise UsageError(f"push: stop must be 'min' or 'max', not {stop!r}")
        names = self._joints(joints)
        out: dict[str, float] = {}
        with self.device.lock:
            self._free(names)
            self._cancel(names)
            for n in names:
                v = self.device.view(n)
                over = _overshoot(self.device, v)
                self.device.place(n, v.low - over if stop == "min" else v.high + over)
                out[n] = self.device.view(n).position
        return out

    def mid(self, joints: str | Sequence[str] | None = None) -> dict[str, float]:
        """Hold joints at the middle of their range (the "middle" pose of a calibration)."""
        names = self._joints(joints)
        with self.device.lock:
            self._free(names)
            self._cancel(names)
            for n in names:
                self.device.place(n, self.device.view(n).mid)
        return {n: self.device.view(n).position for n in names}

    def sweep(
        self,
        joints: str | Sequence[str] | None = None,
        *,
        seconds: float = 3.0,
        dwell_s: float = 0.3,
        paced: bool = False,
    ) -> float:
        """Start moving joints (together) to the low stop, the high stop and back to the middle.

        Args:
            joints: Joints to sweep (default: every joint).
            seconds: Duration of the three moves together (dwells at the stops come on top).
            dwell_s: Time spent pressing against each stop.
            paced: Move as a person watching the client's live table does: each joint the client reads moves on
                only after the client read where it was put, in steps of at most :data:`PACED_MAX_STEP_S` of the
                path, and every stop is read before the hand leaves it. However slowly the client (or this
                simulator) is scheduled, the client sees both stops and no jump; the sweep takes longer then.

        Returns:
            Seconds until the sweep ends (at the least, when paced).
        """
        if not 0.05 <= seconds <= 600 or not 0 <= dwell_s <= 60:
            raise UsageError("sweep: seconds must be 0.05..600 and dwell_s 0..60")
        names = self._joints(joints)
        with self.device.lock:
            self._free(names)
            now = time.monotonic()
            seg = seconds / 3
            plans: dict[str, _Motion] = {}
            for n in names:
                v = self.device.view(n)
                over = _overshoot(self.device, v)
                lo, hi = v.low - over, v.high + over
                path = [
                    (seg, v.position, lo),
                    (dwell_s, lo, lo),
                    (seg, lo, hi),
                    (dwell_s, hi, hi),
                    (seg, hi, v.mid),
                ]
                plans[n] = _Motion(path, now, paced=paced, last_tick=now)
        with self._cv:
            if paced:  # the client's patience counts from now (reads are only counted while a paced sweep runs)
                self._last_read = (self._last_read[0], now)
            self._plans.update(plans)
            self._cv.notify_all()
        return seconds + 2 * dwell_s

    def release(self) -> None:
        """Let go: stop every running motion (the joints stay where they are)."""
        with self._cv:
            self._plans.clear()

    @property
    def busy(self) -> bool:
        """Whether a motion is running (a property, like the simulated Lite operator's)."""
        with self._cv:
            return bool(self._plans)

    def wait(self, timeout_s: float = 60.0) -> bool:
        """Wait until no motion is running; False on timeout."""
        end = time.monotonic() + timeout_s
        with self._cv:
            while self._plans:
                left = end - time.monotonic()
                if left <= 0:
                    return False
                self._cv.wait(min(left, 0.05))
        return True

    def state(self) -> list[JointView]:
        """Every joint's view."""
        with self.device.lock:
            return [self.device.view(n) for n in self.device.joint_names()]

    def close(self) -> None:
        """Stop the motion thread (bounded wait)."""
        self._stop.set()
        self._thread.join(timeout=2.0)

    # ------------------------------------------------------------------------------------------- thread
    def _cancel(self, names: Sequence[str]) -> None:
        with self._cv:
            for n in names:
                self._plans.pop(n, None)

    def _run(self) -> None:
        period = 1.0 / self.rate_hz
        while not self._stop.is_set():
            with self._cv:
                if not self._plans:
                    self._cv.wait(0.1)
                    continue
                plans = dict(self._plans)
            done: list[str] = []
            with self.device.lock:
                now = time.monotonic()
                reads: dict[str, int] = {}
                total = 0
                if any(m.paced for m in plans.values()):  # only a paced sweep waits for the client's reads
                    reads = {n: self.device.reads(n) for n in self.device.joint_names()}
                    total = sum(reads.values())
                    if total != self._last_read[0]:
                        self._last_read = (total, now)
                for n, motion in plans.items():
                    if self.device.view(n).torque:  # the motor took the joint over: the hand lets go
                        done.append(n)
                        continue
                    if not motion.paced:
                        motion.t_s = now - motion.start
                    elif not motion.advance_paced(now, reads[n], total, self._last_read[1]):
                        continue  # waiting for the client to read where the joint is
                    if motion.t_s >= motion.duration:
                        done.append(n)
                    self.device.place(n, motion.target())
                    if motion.paced:  # counted after placing: a read in between saw the old place, wait for the next
                        motion.placed_reads, motion.placed_total = self.device.reads(n), total
            with self._cv:
                for n in done:
                    if self._plans.get(n) is plans[n]:
                        del self._plans[n]
                self._cv.notify_all()
            time.sleep(period)
