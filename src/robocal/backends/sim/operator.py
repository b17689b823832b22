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


def _overshoot(dev: HandDevice, v: JointView) -> float:
    return max(dev.step * 2, 0.02 * (v.high - v.low))


class HandOperator:
    """Moves the joints of a simulated device as a person would, in real time.

    Args:
        device: The simulated robot.
        rate_hz: How often a running motion updates the joints.
    """

    def __init__(self, device: HandDevice, *, rate_hz: float = 200.0) -> None:
        self.device = device
        self.rate_hz = rate_hz
        self._plans: dict[str, list[tuple[float, float, float, float]]] = {}
        """joint → segments (t_start, t_end, from, to) in monotonic seconds."""
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
        self, joints: str | Sequence[str] | None = None, *, seconds: float = 3.0, dwell_s: float = 0.3
    ) -> float:
        """Start moving joints (together) to the low stop, the high stop and back to the middle.

        Args:
            joints: Joints to sweep (default: every joint).
            seconds: Duration of the three moves together (dwells at the stops come on top).
            dwell_s: Time spent pressing against each stop.

        Returns:
            Seconds until the sweep ends.
        """
        if not 0.05 <= seconds <= 600 or not 0 <= dwell_s <= 60:
            raise UsageError("sweep: seconds must be 0.05..600 and dwell_s 0..60")
        names = self._joints(joints)
        with self.device.lock:
            self._free(names)
            now = time.monotonic()
            seg = seconds / 3
            plans: dict[str, list[tuple[float, float, float, float]]] = {}
            for n in names:
                v = self.device.view(n)
                over = _overshoot(self.device, v)
                lo, hi = v.low - over, v.high + over
                t = now
                path = []
                for start, end, dur in (
                    (v.position, lo, seg),
                    (lo, lo, dwell_s),
                    (lo, hi, seg),
                    (hi, hi, dwell_s),
                    (hi, v.mid, seg),
                ):
                    path.append((t, t + dur, start, end))
                    t += dur
                plans[n] = path
        with self._cv:
            self._plans.update(plans)
            self._cv.notify_all()
        return seconds + 2 * dwell_s

    def release(self) -> None:
        """Let go: stop every running motion (the joints stay where they are)."""
        with self._cv:
            self._plans.clear()

    def busy(self) -> bool:
        """Whether a motion is running."""
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
                plans = {n: list(p) for n, p in self._plans.items()}
            now = time.monotonic()
            done: list[str] = []
            with self.device.lock:
                for n, path in plans.items():
                    if self.device.view(n).torque:  # the motor took the joint over: the hand lets go
                        done.append(n)
                        continue
                    target = path[-1][3]
                    for t0, t1, a, b in path:
                        if now < t1:
                            frac = 0.0 if t1 <= t0 else max(0.0, (now - t0) / (t1 - t0))
                            target = a + (b - a) * frac
                            break
                    else:
                        done.append(n)
                    self.device.place(n, target)
            with self._cv:
                for n in done:
                    if self._plans.get(n) == plans[n]:
                        del self._plans[n]
                self._cv.notify_all()
            time.sleep(period)
