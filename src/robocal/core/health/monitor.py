"""Live calibration health for a control loop: :class:`Monitor` flags impossible readings as they happen.

Per tick (``update``), on every joint at once:

* **stops**: ``|q − mid| > half_range + margin`` (a reading past a stop);
* **speed**: ``|q − q_prev| > v_max·dt + noise`` (a change faster than the joint can move);
* **acceleration**: ``|q − (q_prev + Δq_prev)| > a_max·dt² + jitter + 2·noise``: the reading left the path its
  own last velocity predicts by more than the hand or servo can accelerate (a zero lost, a horn that jumped a
  tooth). A reading that only slows down (it lies between the last reading and the prediction: a joint meeting
  a stop) is explained if it stays stopped on the next tick (else it is flagged then, one tick late); one that
  starts from rest towards a command more than ``pin_residual`` away (``q_cmd_rad``: a new target), not past
  it, is explained;
* **pinned** (joints with a leader, checked every 50 ms by :class:`~robocal.core.health.pinned.PinWatch`):
  ``|q_leader − q| > pin_residual`` while the follower stays within ``pin_still`` for ``pin_time``.

The fast path is five numpy calls on preallocated ``(3, N)`` arrays and allocates nothing; the rare ticks where
a bound is broken (or a joint is being watched: outside its stops, a sudden stop) go through a per-joint path
that classifies the event and builds :class:`~robocal.core.health.monitor_types.HealthFlag` values.

The smallest step the acceleration check sees is its bound: with the defaults (50 rad/s², 6 rad/s, two counts of
a 4096-count encoder as noise) 0.79° at 100 Hz, 1.41° at 60 Hz, 1.82° at 50 Hz, 4.12° at 30 Hz (docs/health.md).
"""

from __future__ import annotations

import math
from collections import deque
from numbers import Real

import numpy as np

from ...errors import UsageError
from ..arrays import BoolArray, FloatArray
from .monitor_types import FLAG_KINDS, HealthFlag, MonitorConfig
from .pinned import PinWatch

__all__ = ["Monitor"]

_JITTER = 0.02
"""Relative change of the tick period the bounds absorb before they are recomputed."""

_NO_FLAGS: tuple[HealthFlag, ...] = ()
_SPEED, _STOPS, _ACCEL = 0, 1, 2
"""Rows of the per-tick check arrays."""
_TWO_PI = 2.0 * math.pi
_REAL_KINDS = ("f", "i", "u", "b")
"""numpy dtype kinds ``update`` takes as readings as they are (float, int, unsigned, bool)."""
_KIND_NAMES = {"U": "str", "S": "bytes", "c": "complex", "M": "datetime64", "m": "timedelta64"}


class Monitor:
    """Flags, per tick, readings a correctly calibrated joint cannot produce.

    Build it once before the loop; call :meth:`update` every tick. Nothing is allocated on a tick that raises no
    flag (and watches no joint).

    >>> from robocal.core.health import Monitor, monitor_config
    >>> m = Monitor(monitor_config(["a"], [-1.0], [1.0], 3.0))
    >>> m.update(0.0, np.array([0.2]))
    ()
    >>> [f.kind for f in m.update(0.01, np.array([1.2]))]
    ['outside_stops', 'step']

    Attributes:
        config: What it checks.
        history: The flags raised so far, oldest first (at most ``config.history``).
        counts: Flags raised so far per kind (every kind of :data:`FLAG_KINDS`).
        ticks: Ticks seen.
    """

    def __init__(self, config: MonitorConfig) -> None:
        """Preallocate every per-tick array from ``config``."""
        self.config = config
        n = len(config.joint_names)
        self._n = n
        self._shape = (n,)
        self._names = config.joint_names
        lo = np.array(config.lower_rad, dtype=np.float64)
        up = np.array(config.upper_rad, dtype=np.float64)
        self._lo_m = lo - config.margin_rad
        self._up_m = up + config.margin_rad
        self._vmax = np.array(config.max_speed_rad_s, dtype=np.float64)
        self._amax = np.array(config.max_accel_rad_s2, dtype=np.float64)
        self._noise = np.array(config.noise_rad, dtype=np.float64)
        self._wraps = config.wraps
        # references subtracted from q: [previous reading, mid-range, predicted reading]
        self._ref: FloatArray = np.full((3, n), np.nan)
        self._ref[_STOPS] = 0.5 * (lo + up)
        self._prev_pred = self._ref[::2]  # [previous, predicted], written by one call per tick
        # [0, q − previous, q − mid, q − predicted]: rows 1-3 are the checks (signed), rows 0-1 what the next
        # tick's [previous, predicted] are q plus
        self._work: FloatArray = np.zeros((4, n))
        self._diff = self._work[1:]
        self._zero_dq = self._work[0:2]
        self._abs: FloatArray = np.zeros((3, n))
        self._bound: FloatArray = np.full((3, n), np.inf)
        self._bound[_STOPS] = 0.5 * (up - lo) + config.margin_rad
        self._hit: BoolArray = np.zeros((3, n), dtype=bool)
        self._pins = PinWatch(config)
        self._dt_ref = math.nan
        self._accel_skip = 0
        self._t_prev = math.nan
        self._outside: set[int] = set()
        self._pending: dict[int, float] = {}  # joint -> the change of a sudden stop, judged on the next tick
        self._hold_until = [-math.inf] * n
        self.history: deque[HealthFlag] = deque(maxlen=config.history)
        self.counts: dict[str, int] = dict.fromkeys(FLAG_KINDS, 0)
        self.ticks = 0

    def reset(self) -> None:
        """Forget the past readings (after a pause in the loop); the history and counts stay."""
        self._prev_pred[...] = np.nan
        self._t_prev = math.nan
        self._dt_ref = math.nan
        self._bound[_SPEED] = np.inf
        self._bound[_ACCEL] = np.inf
        self._outside.clear()
        self._pins.reset()
        self._pending.clear()

    def _set_bounds(self, dt: float) -> None:
        """Speed and acceleration bounds for a tick period of about ``dt`` (within ±:data:`_JITTER`)."""
        dt_hi = dt * (1.0 + _JITTER)
        np.multiply(self._vmax, dt_hi, out=self._bound[_SPEED])
        self._bound[_SPEED] += self._noise
        # a·dt² for the hand, v·Δdt for the period's jitter between two ticks, noise on both readings
        np.multiply(self._amax, dt_hi * dt_hi, out=self._bound[_ACCEL])
        self._bound[_ACCEL] += self._vmax * (2.0 * _JITTER * dt) + 2.0 * self._noise
        self._dt_ref = dt

    def update(
        self,
        t_s: float,
        q_rad: FloatArray,
        q_cmd_rad: FloatArray | None = None,
        q_leader_rad: FloatArray | None = None,
    ) -> tuple[HealthFlag, ...]:
        """Check one tick's readings.

        Args:
            t_s: Time of the reading, s (any clock that only goes forward).
            q_rad: Joint readings, shape ``(N,)`` float64, in the joints' calibrated frame, rad (NaN: not read).
            q_cmd_rad: Commanded positions, shape ``(N,)`` (optional): a step from rest towards a command more
                than ``pin_residual_rad`` away (a new target), and not beyond it, is not flagged.
            q_leader_rad: Leader readings of the paired joints, shape ``(N,)`` (optional; NaN or anything for
                unpaired joints).

        Returns:
            The flags this tick raised (empty on almost every tick); they are also appended to :attr:`history`.

        Raises:
            UsageError: ``t_s`` is not finite or did not advance past the previous tick's time; an array that is
                not one real number per joint (strings, bytes, complex numbers and dates are refused).
        """
        if not math.isfinite(t_s):
            raise UsageError(f"monitor: time {t_s} s is not a finite number")
        dt = t_s - self._t_prev
        if dt <= 0.0:
            raise UsageError(f"monitor: time {t_s} s is not after the previous tick's {self._t_prev} s")
        if not self._fits(q_rad):
            q_rad = self._readings("q_rad", q_rad)
        if q_cmd_rad is not None and not self._fits(q_cmd_rad):
            q_cmd_rad = self._readings("q_cmd_rad", q_cmd_rad)
        if q_leader_rad is not None and not self._fits(q_leader_rad):
            q_leader_rad = self._readings("q_leader_rad", q_leader_rad)
        self._t_prev = t_s
        self.ticks += 1
        if not abs(dt - self._dt_ref) <= _JITTER * self._dt_ref:  # first ticks, or the period changed
            self._new_period(dt)
        elif self._accel_skip:
            self._accel_skip -= 1
            if not self._accel_skip:
                self._set_bounds(self._dt_ref)
        np.subtract(q_rad, self._ref, out=self._diff)
        np.abs(self._diff, out=self._abs)
        np.greater(self._abs, self._bound, out=self._hit)
        flags = _NO_FLAGS
        if np.count_nonzero(self._hit) or self._outside or self._pending:
            flags = self._classify(t_s, dt, q_rad, q_cmd_rad)
        if q_leader_rad is not None:
            pinned = self._pins.check(t_s, q_rad, q_leader_rad)
            if pinned:
                flags = flags + self._record(pinned)
        np.add(q_rad, self._zero_dq, out=self._prev_pred)
        return flags

    def _fits(self, values: object) -> bool:
        """``values`` is an ``(N,)`` numpy-style array of real numbers (taken as it is, without a copy)."""
        return (
            getattr(values, "shape", None) == self._shape
            and getattr(getattr(values, "dtype", None), "kind", None) in _REAL_KINDS
        )

    def _readings(self, what: str, values: object) -> FloatArray:
        """``values`` (not an ``(N,)`` real array already) as one float per joint, or a UsageError naming ``what``.

        Strings (even of numbers), bytes, complex numbers and dates are refused, not parsed or cut to their real
        part; ``None`` in a list is NaN (a joint not read), as numpy converts it.
        """
        try:
            raw = np.asarray(values)
        except (TypeError, ValueError):
            raise UsageError(f"monitor: {what} is not numbers ({type(values).__name__})") from None
        kind = raw.dtype.kind
        bad = _KIND_NAMES.get(kind, raw.dtype.name) if kind not in (*_REAL_KINDS, "O") else None
        if kind == "O":
            odd = next((v for v in raw.flat if v is not None and not isinstance(v, Real)), None)
            bad = None if odd is None else type(odd).__name__
        if bad is not None:
            raise UsageError(
                f"monitor: {what} is not real numbers ({bad}); expected one float per joint ({', '.join(self._names)})"
            )
        try:
            out = raw.astype(np.float64)
        except (TypeError, ValueError):
            raise UsageError(f"monitor: {what} is not numbers ({type(values).__name__})") from None
        if out.shape != self._shape:
            raise UsageError(
                f"monitor: {what} has shape {out.shape}; expected ({self._n},), one value per joint "
                f"({', '.join(self._names)})"
            )
        return out

    def _new_period(self, dt: float) -> None:
        """The tick period changed (or this is the first tick): new bounds, no acceleration check for 2 ticks.

        The prediction ``q + Δq`` assumes the next period equals this one; across a change it does not hold.
        """
        if math.isnan(dt):  # first tick
            return
        self._set_bounds(dt)
        self._bound[_ACCEL] = np.inf
        self._accel_skip = 2

    def _classify(
        self,
        t_s: float,
        dt: float,
        q: FloatArray,
        q_cmd: FloatArray | None,
    ) -> tuple[HealthFlag, ...]:
        """The per-joint path: what each broken bound means (before the state moves on to this tick)."""
        out: list[HealthFlag] = []
        hit = self._hit
        branch_now: set[int] = set()
        for j in np.flatnonzero(hit[_STOPS]).tolist():
            if j not in self._outside:
                self._outside.add(j)
                flag = self._outside_flag(t_s, j, float(q[j]))
                if flag.kind == "wrong_branch":
                    branch_now.add(j)
                out.append(flag)
        for j in [j for j in self._outside if not hit[_STOPS, j]]:
            self._outside.discard(j)
        stepped = np.flatnonzero(hit[_SPEED] | hit[_ACCEL]).tolist()
        for j in [j for j in self._pending if j not in stepped]:
            del self._pending[j]  # it stayed stopped: the stop was real
        for j in stepped:
            step = self._step_flag(t_s, dt, j, q, q_cmd)
            if step is not None and not (step.kind == "wrong_branch" and j in branch_now):
                out.append(step)
        return self._record(out) if out else _NO_FLAGS

    def _record(self, flags: list[HealthFlag]) -> tuple[HealthFlag, ...]:
        """``flags`` added to the history and counts."""
        self.history.extend(flags)
        for f in flags:
            self.counts[f.kind] += 1
        return tuple(flags)

    def _outside_flag(self, t_s: float, j: int, q: float) -> HealthFlag:
        """``outside_stops``, or ``wrong_branch`` when a whole turn puts a wrapping joint inside its stops."""
        lo, up = float(self._lo_m[j]), float(self._up_m[j])
        if self._wraps[j]:
            k = math.floor((lo - q) / _TWO_PI) + 1  # the first whole turn that lifts q above lo
            for kk in (k, k - 1):
                if kk and lo <= q + kk * _TWO_PI <= up:
                    return HealthFlag(t_s, self._names[j], "wrong_branch", q, q + kk * _TWO_PI)
        return HealthFlag(t_s, self._names[j], "outside_stops", q, up if q > up else lo)

    def _step_flag(
        self, t_s: float, dt: float, j: int, q: FloatArray, q_cmd: FloatArray | None
    ) -> HealthFlag | None:
        """A step on joint ``j``: flagged, or explained (a stop met, a commanded start, a hold-off) as None."""
        qj = float(q[j])
        dq = float(self._diff[_SPEED, j])
        innov = float(self._diff[_ACCEL, j])
        prev = qj - dq
        last_dq = (qj - innov) - prev  # the previous tick's change, what the prediction continued
        noise = float(self._noise[j])
        speed_hit = bool(self._hit[_SPEED, j])
        name = self._names[j]
        if self._wraps[j]:
            k = round(dq / _TWO_PI)
            if k and abs(dq - k * _TWO_PI) <= float(self._vmax[j]) * dt + noise:
                self._keep_velocity(j, qj, last_dq, t_s)
                return HealthFlag(t_s, name, "wrong_branch", dq, k * _TWO_PI)
        pending = self._pending.pop(j, None)
        lo, hi = min(prev, qj - innov), max(prev, qj - innov)
        if not speed_hit and lo - 2.0 * noise <= qj <= hi + 2.0 * noise:  # noise on both readings
            # slowed down or stopped on the way: a stop met, if it stays stopped (judged on the next ticks)
            self._pending[j] = innov if pending is None else pending
            return None
        if pending is not None and self._hit[_ACCEL, j]:
            # it "stopped" and moves on at once: no stop was met, the reading jumped
            if t_s < self._hold_until[j]:
                return None
            self._hold_until[j] = t_s + self.config.step_holdoff_s
            return HealthFlag(t_s, name, "step", pending, float(self._bound[_ACCEL, j]))
        if not speed_hit and q_cmd is not None:
            gap = float(q_cmd[j]) - prev
            resting = abs(last_dq) <= noise and abs(gap) > self.config.pin_residual_rad
            if resting and dq * gap > 0 and abs(dq) <= abs(gap) + noise:
                return None  # a start from rest towards a far command (a new target), not past it
        if t_s < self._hold_until[j]:
            return None
        self._keep_velocity(j, qj, last_dq, t_s)
        if math.isnan(innov) or (speed_hit and not self._hit[_ACCEL, j]):
            return HealthFlag(t_s, name, "step", dq, float(self._bound[_SPEED, j]))
        return HealthFlag(t_s, name, "step", innov, float(self._bound[_ACCEL, j]))

    def _keep_velocity(self, j: int, qj: float, last_dq: float, t_s: float) -> None:
        """After a jump: predict the next reading from the velocity before it, and hold further step flags off.

        ``update`` sets the prediction to ``q + Δq`` after this; Δq is replaced by the change before the jump.
        """
        self._diff[_SPEED, j] = last_dq if math.isfinite(last_dq) else 0.0
        self._hold_until[j] = t_s + self.config.step_holdoff_s
