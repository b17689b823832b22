"""Automatic hard-stop search: a backend-neutral state machine and the per-joint zero/span math.

Pure numpy, no I/O, no clock: a driver (a Robstride MIT loop, a Feetech or Dynamixel servo, a simulator)
feeds :class:`Sample` values — time, position, velocity, torque, flags — into :meth:`StopSearch.step` and
carries out the :class:`Command` it returns. Angles are in the joint frame (rad, after the axis direction),
torques in N·m on the joint (positive along +q).

One search drives one joint into one stop (``direction`` −1 or +1)::

    approach ──(armed: travel ≥ min_travel and speed reached; |v| < v_th AND (τ ≥ τ_th OR lag ≥ lag_th)
                for dwell_s)──▶ press (hold at a lower push, read position) ──▶ back off ──▶ [second touch] ──▶ done

* **Arming.** The stall test is armed only after ``min_travel_rad`` of travel *and* once the joint reached
  ``arm_speed_fraction`` of the commanded speed, so breakaway friction (stiction) and the velocity loop's
  saturation during acceleration never look like a stop.
* **Target.** The position target ramps at ``speed_rad_s`` but never leads the joint by more than
  ``max_lag_rad``; with a position gain ``kp`` a driver sets ``max_lag_rad = cap/kp`` so the push at the stop is
  bounded by the cap even before the motor's own torque limit.
* **Suspect evidence.** An overload flag or a lost reply never declares a stop by itself: the search asks for a
  re-read (``Command.action == "reread"``: clear the latch, read the position). If the joint was armed and
  slow, and the re-read position agrees with the last good one within ``confirm_tol_rad``, the stop is
  confirmed (test ``overload+reread`` or ``no-reply+reread``); otherwise the approach continues (at most
  ``max_suspects`` times). Replies missing for longer than ``reply_timeout_s`` fail the search (``no_reply``).
* **Bounds.** Travel beyond ``max_travel_rad`` from the start fails the search (``missing_stop``); a search
  running longer than ``max_time_s`` fails it too (``timeout``). Both end with ``Command.action == "limp"``.
* **Stiffness.** At contact the joint is pressed at the cap (reading ``q_hi``, ``τ_hi``), then at
  ``press_fraction`` of it (``q_lo``, ``τ_lo``): ``k̂ = (τ_hi − τ_lo)/(q_hi − q_lo)``. A spring-damper stop gives
  ``q = q_surface + (τ_motor + τ_gravity)/k``, so the contact surface is
  ``q_surface = q_hi − (τ_hi + τ_g(q_hi))/k̂`` (``τ_g`` only when a gravity model is given).

:func:`joint_zero` combines the two stops of a joint (or one stop and the profile's stop angle) into the
position offset (``q_joint = s − offset``), the span and its plausibility against the expected span.

Failure codes (stable, in reports): ``missing_stop``, ``timeout``, ``no_reply``, ``touch_mismatch``,
``blocked`` (never reached the commanded speed before a stall: stuck at the start), ``span_mismatch``,
``stop_mismatch`` (a one-sided stop far from the expected angle), ``aborted``.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np

from ..errors import InvalidCalibrationError

__all__ = [
    "FAIL_CODES",
    "TESTS",
    "Command",
    "JointStops",
    "Sample",
    "SearchConfig",
    "StopResult",
    "StopSearch",
    "joint_zero",
    "summarise",
    "with_gravity",
]

FAIL_CODES = (
    "missing_stop",
    "timeout",
    "no_reply",
    "touch_mismatch",
    "blocked",
    "span_mismatch",
    "stop_mismatch",
    "aborted",
)
"""Why a search or a joint failed (``ok`` otherwise)."""
TESTS = ("torque", "lag", "overload+reread", "no-reply+reread", "transit-stall")
"""Which test declared the stop."""


@dataclass(frozen=True)
class SearchConfig:
    """Parameters of one stop search (joint frame; SI units).

    Attributes:
        speed_rad_s: Approach speed (> 0). The notes suggest 5–20 °/s at the output.
        torque_cap_nm: Push torque cap (> 0): the driver limits the motor to it; the press uses it.
        max_travel_rad: Travel bound from the start position (expected distance to the stop + margin).
        max_time_s: Time bound of the whole search (approach, press, back-off, second touch).
        max_lag_rad: The target never leads the joint by more than this (``cap/kp`` for a PD drive).
        torque_fraction: Torque test threshold as a fraction of the cap (above any stiction to ignore).
        lag_fraction: Lag test threshold as a fraction of ``max_lag_rad``.
        v_fraction: Stall velocity threshold as a fraction of the speed.
        arm_speed_fraction: The joint must reach this fraction of the speed before the test is armed.
        min_travel_rad: Travel before the test is armed.
        dwell_s: How long the stall condition must hold.
        press_fraction: Second press level (fraction of the cap) for the stiffness estimate.
        settle_s: Settling time at each press level before reading.
        backoff_rad: Retreat after contact.
        second_touch: Touch the stop a second time; both touches must agree within ``touch_tol_rad``.
        touch_tol_rad: Agreement of the two touches.
        confirm_tol_rad: A re-read position confirms a suspect stop when within this of the last good one.
        reply_timeout_s: Replies missing for longer than this fail the search.
        max_suspects: Unconfirmed suspect events allowed before the search fails.
        gravity_nm: Gravity torque on the joint as a function of q (joint frame), or None (taken as 0).
    """

    speed_rad_s: float
    torque_cap_nm: float
    max_travel_rad: float
    max_time_s: float
    max_lag_rad: float
    torque_fraction: float = 0.9
    lag_fraction: float = 0.9
    v_fraction: float = 0.1
    arm_speed_fraction: float = 0.7
    min_travel_rad: float = math.radians(3.0)
    dwell_s: float = 0.2
    press_fraction: float = 0.5
    settle_s: float = 0.2
    backoff_rad: float = math.radians(5.0)
    second_touch: bool = False
    touch_tol_rad: float = math.radians(0.5)
    confirm_tol_rad: float = math.radians(1.0)
    reply_timeout_s: float = 0.5
    max_suspects: int = 3
    gravity_nm: Callable[[float], float] | None = field(default=None, compare=False)

    def __post_init__(self) -> None:
        for name in (
            "speed_rad_s",
            "torque_cap_nm",
            "max_travel_rad",
            "max_time_s",
            "max_lag_rad",
            "dwell_s",
        ):
            value = getattr(self, name)
            if not (isinstance(value, (int, float)) and math.isfinite(value) and value > 0):
                raise InvalidCalibrationError(
                    f"stop search: {name} must be a positive finite number, got {value!r}"
                )
        for name in ("torque_fraction", "lag_fraction", "v_fraction", "arm_speed_fraction", "press_fraction"):
            value = getattr(self, name)
            if not (math.isfinite(value) and 0 < value < 1.5):
                raise InvalidCalibrationError(f"stop search: {name} must be in (0, 1.5), got {value!r}")
        for name in ("min_travel_rad", "settle_s", "backoff_rad", "touch_tol_rad", "confirm_tol_rad"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value >= 0):
                raise InvalidCalibrationError(f"stop search: {name} must be ≥ 0, got {value!r}")

    def gravity(self, q_rad: float) -> float:
        """Gravity torque at ``q_rad`` (0 without a model)."""
        return 0.0 if self.gravity_nm is None else float(self.gravity_nm(q_rad))


@dataclass(frozen=True)
class Sample:
    """One reading of a joint.

    Attributes:
        t_s: Time (s, any monotonic origin; a simulator's clock).
        q_rad: Position (joint frame); NaN when ``ok`` is False.
        v_rad_s: Velocity; NaN when unknown.
        torque_nm: Torque the motor applies (joint frame, signed); NaN when the backend has none.
        ok: A reply arrived.
        overload: The motor reports an overload / protection latch.
    """

    t_s: float
    q_rad: float
    v_rad_s: float = math.nan
    torque_nm: float = math.nan
    ok: bool = True
    overload: bool = False


@dataclass(frozen=True)
class Command:
    """What the driver does next.

    ``action``:

    * ``drive`` — position target ``q_target_rad`` with velocity feed-forward ``v_target_rad_s``, torque
      limited to ``torque_limit_nm``;
    * ``push`` — push along ``direction`` with ``torque_limit_nm`` (a torque command, or a goal beyond the stop
      with the torque limit), ``q_target_rad`` is the goal a position servo uses;
    * ``reread`` — clear any latch (torque off briefly), read the position, resume;
    * ``hold`` — the search is over: hold ``q_target_rad`` (torque limited);
    * ``limp`` — the search failed: torque off at once.
    """

    action: str
    q_target_rad: float = math.nan
    v_target_rad_s: float = 0.0
    torque_limit_nm: float = 0.0


@dataclass(frozen=True)
class StopResult:
    """The outcome of one stop search.

    Attributes:
        direction: −1 (lower stop) or +1 (upper stop).
        code: ``ok`` or one of :data:`FAIL_CODES`.
        reason: One sentence for humans ("" when ok).
        q_stop_rad: Contact surface (pressed position corrected by ``(τ + τ_g)/k̂``); NaN when failed.
        q_pressed_rad: Position pressed at the cap (mean over the dwell).
        torque_nm: Detection torque (mean over the dwell, signed).
        stiffness_nm_per_rad: Estimated stop stiffness, NaN when not measured.
        test: Which test declared the stop (:data:`TESTS`) or "".
        t_detect_s: Time of the detection from the search start.
        duration_s: Time of the whole search.
        travel_rad: Largest travel from the start.
        peak_torque_nm: Largest |torque| read.
        touches: Contact surfaces of each touch (one or two).
    """

    direction: int
    code: str
    reason: str = ""
    q_stop_rad: float = math.nan
    q_pressed_rad: float = math.nan
    torque_nm: float = math.nan
    stiffness_nm_per_rad: float = math.nan
    test: str = ""
    t_detect_s: float = math.nan
    duration_s: float = math.nan
    travel_rad: float = 0.0
    peak_torque_nm: float = 0.0
    touches: tuple[float, ...] = ()

    @property
    def ok(self) -> bool:
        """Whether the stop was found."""
        return self.code == "ok"

    def to_report(self) -> dict[str, Any]:
        """Plain values for a JSON report (degrees where a person reads them)."""

        def deg(x: float) -> float | None:
            return None if not math.isfinite(x) else round(math.degrees(x), 4)

        def num(x: float, nd: int = 4) -> float | None:
            return None if not math.isfinite(x) else round(x, nd)

        return {
            "code": self.code,
            "reason": self.reason,
            "q_stop_deg": deg(self.q_stop_rad),
            "q_pressed_deg": deg(self.q_pressed_rad),
            "detection_torque_nm": num(self.torque_nm),
            "stiffness_nm_per_rad": num(self.stiffness_nm_per_rad, 2),
            "test": self.test,
            "t_detect_s": num(self.t_detect_s, 3),
            "duration_s": num(self.duration_s, 3),
            "travel_deg": deg(self.travel_rad),
            "peak_torque_nm": num(self.peak_torque_nm),
            "touches_deg": [deg(x) for x in self.touches],
        }


_APPROACH, _CONFIRM, _PRESS_HI, _PRESS_LO, _BACKOFF, _DONE = range(6)


class StopSearch:
    """Drives one joint into one stop: feed it samples, do what its commands say.

    Usage::

        search = StopSearch(+1, config)
        cmd = search.start(sample)
        while not search.done:
            cmd = search.step(driver.execute(cmd))
        result = search.result
    """

    def __init__(self, direction: int, config: SearchConfig) -> None:
        if direction not in (-1, 1):
            raise InvalidCalibrationError(f"stop search: direction must be -1 or +1, got {direction!r}")
        self.direction = direction
        self.config = config
        self._phase = _APPROACH
        self._result: StopResult | None = None
        self._t0 = math.nan
        self._q0 = math.nan
        self._t_last = math.nan
        self._target = math.nan
        self._armed = False
        self._stall_since: float | None = None
        self._window: list[Sample] = []
        self._last_good: Sample | None = None
        self._no_reply_since: float | None = None
        self._suspects = 0
        self._suspect_kind = ""
        self._travel = 0.0
        self._peak = 0.0
        self._touches: list[float] = []
        self._touch_start_q = math.nan
        self._phase_t0 = math.nan
        self._hi: tuple[float, float] | None = None
        self._detect: tuple[float, float, str] | None = None  # (t, torque, test)
        self._stiffness: list[float] = []
        self._pressed: list[float] = []
        self._torques: list[float] = []
        self._backoff_goal = math.nan

    # -- public -------------------------------------------------------------------------------------------
    @property
    def done(self) -> bool:
        """Whether the search is over (:attr:`result` is set)."""
        return self._result is not None

    @property
    def result(self) -> StopResult:
        """The result (only once :attr:`done`)."""
        if self._result is None:
            raise RuntimeError("stop search still running")
        return self._result

    @property
    def armed(self) -> bool:
        """Whether the stall test is armed (for a live view)."""
        return self._armed

    @property
    def phase(self) -> str:
        """The current phase name (for a live view)."""
        return ("approach", "confirm", "press", "press", "backoff", "done")[self._phase]

    def start(self, sample: Sample) -> Command:
        """Begin at the joint's current reading (must be a good reply)."""
        if not sample.ok or not math.isfinite(sample.q_rad):
            return self._fail("no_reply", "no position reading at the start of the search", sample)
        self._t0 = self._t_last = sample.t_s
        self._q0 = self._touch_start_q = sample.q_rad
        self._target = sample.q_rad
        self._last_good = sample
        return self._drive_cmd()

    def abort(self, reason: str = "aborted") -> StopResult:
        """End the search now (Ctrl-C, a fault elsewhere): the result is ``aborted``."""
        if self._result is None:
            self._result = self._make_fail("aborted", reason)
        return self._result

    def step(self, sample: Sample) -> Command:
        """Feed the next reading; returns the next command (``hold`` or ``limp`` once done)."""
        cfg = self.config
        if self._result is not None:
            return self._final_cmd()
        dt = sample.t_s - self._t_last if math.isfinite(self._t_last) else 0.0
        self._t_last = sample.t_s
        if sample.t_s - self._t0 > cfg.max_time_s:
            return self._fail(
                "timeout",
                f"no stop within the time bound {cfg.max_time_s:.1f} s "
                f"(travel {math.degrees(self._travel):.1f}°)",
                sample,
            )
        if not sample.ok or not math.isfinite(sample.q_rad):
            if self._no_reply_since is None:
                self._no_reply_since = sample.t_s
            if sample.t_s - self._no_reply_since > cfg.reply_timeout_s:
                return self._fail(
                    "no_reply", f"no reply for {sample.t_s - self._no_reply_since:.2f} s", sample
                )
            if self._phase in (_APPROACH, _PRESS_HI, _PRESS_LO) and self._phase != _CONFIRM:
                return self._suspect("no-reply")
            return Command("reread", self._target, 0.0, cfg.torque_cap_nm)
        self._no_reply_since = None
        if math.isfinite(sample.torque_nm):
            self._peak = max(self._peak, abs(sample.torque_nm))
        self._travel = max(self._travel, abs(sample.q_rad - self._q0))
        if self._phase == _CONFIRM:
            return self._confirm(sample)
        if sample.overload and self._phase in (_APPROACH, _PRESS_HI, _PRESS_LO):
            self._last_good = sample
            return self._suspect("overload")
        self._last_good = sample
        if self._travel > cfg.max_travel_rad:
            return self._fail(
                "missing_stop",
                f"no stop within the travel bound {math.degrees(cfg.max_travel_rad):.1f}°",
                sample,
            )
        if self._phase == _APPROACH:
            return self._approach(sample, dt)
        if self._phase in (_PRESS_HI, _PRESS_LO):
            return self._press(sample)
        return self._backoff(sample)

    # -- phases -------------------------------------------------------------------------------------------
    def _drive_cmd(self) -> Command:
        return Command(
            "drive", self._target, self.direction * self.config.speed_rad_s, self.config.torque_cap_nm
        )

    def _approach(self, s: Sample, dt: float) -> Command:
        cfg, d = self.config, self.direction
        self._target += d * cfg.speed_rad_s * max(dt, 0.0)
        lead = d * (self._target - s.q_rad)
        clamped = lead > cfg.max_lag_rad
        if clamped:
            self._target = s.q_rad + d * cfg.max_lag_rad
        v = s.v_rad_s if math.isfinite(s.v_rad_s) else math.nan
        travel = abs(s.q_rad - self._touch_start_q)
        min_travel = (
            cfg.min_travel_rad if not self._touches else min(cfg.min_travel_rad, 0.5 * cfg.backoff_rad)
        )
        if (
            not self._armed
            and travel >= min_travel
            and math.isfinite(v)
            and d * v >= cfg.arm_speed_fraction * cfg.speed_rad_s
        ):
            self._armed = True
        slow = math.isfinite(v) and abs(v) < cfg.v_fraction * cfg.speed_rad_s
        lag = d * (self._target - s.q_rad)
        torque_hit = math.isfinite(s.torque_nm) and d * s.torque_nm >= cfg.torque_fraction * cfg.torque_cap_nm
        lag_hit = lag >= cfg.lag_fraction * cfg.max_lag_rad
        if self._armed and slow and (torque_hit or lag_hit):
            if self._stall_since is None:
                self._stall_since = s.t_s
                self._window = []
            self._window.append(s)
            if s.t_s - self._stall_since >= cfg.dwell_s:
                test = "torque" if torque_hit else "lag"
                return self._contact(s, test)
        else:
            self._stall_since = None
            self._window = []
        return Command("drive", self._target, 0.0 if clamped else d * cfg.speed_rad_s, cfg.torque_cap_nm)

    def _contact(self, s: Sample, test: str) -> Command:
        cfg = self.config
        win = self._window or [s]
        q_hi = float(np.mean([w.q_rad for w in win]))
        torques = [w.torque_nm for w in win if math.isfinite(w.torque_nm)]
        tau_hi = float(np.mean(torques)) if torques else self.direction * cfg.torque_cap_nm
        if self._detect is None:
            self._detect = (s.t_s - self._t0, tau_hi, test)
        self._hi = (q_hi, tau_hi)
        self._pressed.append(q_hi)
        self._torques.append(tau_hi)
        self._phase = _PRESS_LO
        self._phase_t0 = s.t_s
        self._window = []
        return self._press_cmd(cfg.press_fraction)

    def _press_cmd(self, fraction: float) -> Command:
        cfg, d = self.config, self.direction
        assert self._hi is not None
        goal = self._hi[0] + d * cfg.max_lag_rad
        return Command("push", goal, 0.0, fraction * cfg.torque_cap_nm)

    def _press(self, s: Sample) -> Command:
        cfg = self.config
        elapsed = s.t_s - self._phase_t0
        if elapsed < cfg.settle_s:
            return self._press_cmd(cfg.press_fraction)
        self._window.append(s)
        if elapsed < cfg.settle_s + cfg.dwell_s:
            return self._press_cmd(cfg.press_fraction)
        assert self._hi is not None
        q_lo = float(np.mean([w.q_rad for w in self._window]))
        torques = [w.torque_nm for w in self._window if math.isfinite(w.torque_nm)]
        tau_lo = (
            float(np.mean(torques)) if torques else self.direction * cfg.press_fraction * cfg.torque_cap_nm
        )
        q_hi, tau_hi = self._hi
        dq = q_hi - q_lo
        k = (tau_hi - tau_lo) / dq if abs(dq) > 1e-9 else math.inf
        if not (math.isfinite(k) and k > 0):
            k = math.nan
        self._stiffness.append(k)
        self._touches.append(self._surface(q_hi, tau_hi, k))
        return self._start_backoff(s)

    def _surface(self, q: float, tau: float, k: float) -> float:
        if not (math.isfinite(k) and k > 0):
            return q
        return q - (tau + self.config.gravity(q)) / k

    def _start_backoff(self, s: Sample) -> Command:
        cfg = self.config
        self._phase = _BACKOFF
        self._phase_t0 = s.t_s
        self._backoff_goal = self._touches[-1] - self.direction * cfg.backoff_rad
        self._target = s.q_rad
        return Command("drive", s.q_rad, 0.0, cfg.torque_cap_nm)

    def _backoff(self, s: Sample) -> Command:
        cfg, d = self.config, self.direction
        step = cfg.speed_rad_s * max(s.t_s - self._phase_t0, 0.0)
        self._phase_t0 = s.t_s
        remaining = d * (self._target - self._backoff_goal)
        self._target -= d * min(step, max(remaining, 0.0))
        if d * (s.q_rad - self._backoff_goal) <= math.radians(0.5) or (
            remaining <= 0
            and abs(s.v_rad_s if math.isfinite(s.v_rad_s) else 0.0) < cfg.v_fraction * cfg.speed_rad_s
        ):
            if cfg.second_touch and len(self._touches) == 1:
                self._phase = _APPROACH
                self._armed = False
                self._stall_since = None
                self._touch_start_q = s.q_rad
                self._target = s.q_rad
                return self._drive_cmd()
            return self._finish(s)
        return Command(
            "drive", self._target, -d * cfg.speed_rad_s if remaining > 0 else 0.0, cfg.torque_cap_nm
        )

    def _finish(self, s: Sample) -> Command:
        cfg = self.config
        touches = tuple(self._touches)
        if len(touches) == 2 and abs(touches[0] - touches[1]) > cfg.touch_tol_rad:
            return self._fail(
                "touch_mismatch",
                f"the two touches disagree by {math.degrees(abs(touches[0] - touches[1])):.2f}° "
                f"(tolerance {math.degrees(cfg.touch_tol_rad):.2f}°)",
                s,
            )
        ks = [k for k in self._stiffness if math.isfinite(k)]
        assert self._detect is not None
        self._result = StopResult(
            direction=self.direction,
            code="ok",
            q_stop_rad=float(np.mean(touches)),
            q_pressed_rad=float(np.mean(self._pressed)),
            torque_nm=self._detect[1],
            stiffness_nm_per_rad=float(np.mean(ks)) if ks else math.nan,
            test=self._detect[2],
            t_detect_s=self._detect[0],
            duration_s=s.t_s - self._t0,
            travel_rad=self._travel,
            peak_torque_nm=self._peak,
            touches=touches,
        )
        self._phase = _DONE
        return Command("hold", s.q_rad, 0.0, cfg.torque_cap_nm)

    # -- suspect evidence ---------------------------------------------------------------------------------
    def _suspect(self, kind: str) -> Command:
        self._suspect_kind = kind
        self._resume_phase = self._phase
        self._phase = _CONFIRM
        return Command("reread", self._target, 0.0, self.config.torque_cap_nm)

    def _confirm(self, s: Sample) -> Command:
        cfg = self.config
        good = self._last_good
        resume = self._resume_phase
        self._phase = resume
        v_good = good.v_rad_s if good is not None and math.isfinite(good.v_rad_s) else math.inf
        agrees = good is not None and abs(s.q_rad - good.q_rad) <= cfg.confirm_tol_rad
        slow = abs(v_good) < max(cfg.v_fraction, 0.5) * cfg.speed_rad_s
        if resume in (_PRESS_HI, _PRESS_LO) and agrees:
            # The stop is already found; the latch came while pressing: finish this touch without k̂.
            q = s.q_rad
            self._stiffness.append(math.nan)
            self._touches.append(q)
            self._last_good = s
            return self._start_backoff(s)
        if resume == _APPROACH and self._armed and slow and agrees:
            test = "overload+reread" if self._suspect_kind == "overload" else "no-reply+reread"
            q = s.q_rad
            if self._detect is None:
                self._detect = (s.t_s - self._t0, good.torque_nm if good is not None else math.nan, test)
            self._pressed.append(q)
            self._stiffness.append(math.nan)
            self._touches.append(q)
            self._last_good = s
            return self._start_backoff(s)
        self._suspects += 1
        self._last_good = s
        if self._suspects > cfg.max_suspects:
            return self._fail(
                "no_reply" if self._suspect_kind == "no-reply" else "blocked",
                f"{self._suspects} {self._suspect_kind} events the position re-read did not confirm as a stop",
                s,
            )
        self._stall_since = None
        self._target = s.q_rad
        return self._drive_cmd()

    # -- ends ---------------------------------------------------------------------------------------------
    def _make_fail(self, code: str, reason: str, s: Sample | None = None) -> StopResult:
        t = s.t_s if s is not None and math.isfinite(self._t0) else math.nan
        return StopResult(
            direction=self.direction,
            code=code,
            reason=reason,
            duration_s=t - self._t0 if math.isfinite(t) else math.nan,
            travel_rad=self._travel,
            peak_torque_nm=self._peak,
            touches=tuple(self._touches),
        )

    def _fail(self, code: str, reason: str, s: Sample) -> Command:
        self._result = self._make_fail(code, reason, s)
        self._phase = _DONE
        return Command("limp")

    def _final_cmd(self) -> Command:
        assert self._result is not None
        if not self._result.ok:
            return Command("limp")
        return Command(
            "hold", self._last_good.q_rad if self._last_good else math.nan, 0.0, self.config.torque_cap_nm
        )


@dataclass(frozen=True)
class JointStops:
    """Both (or one) stops of a joint combined into a zero.

    Attributes:
        name: Joint name.
        code: ``ok`` or a failure code (:data:`FAIL_CODES`).
        reason: One sentence ("" when ok).
        lower: Lower-stop search result, or None when not searched.
        upper: Upper-stop search result, or None.
        offset_rad: Position offset in the joint frame, ``q_joint = s − offset`` (NaN when failed).
        span_rad: Measured span (upper − lower surfaces), NaN for one-sided.
        expected_span_rad: Expected span (URDF or profile), NaN when unknown.
    """

    name: str
    code: str
    reason: str
    lower: StopResult | None
    upper: StopResult | None
    offset_rad: float
    span_rad: float = math.nan
    expected_span_rad: float = math.nan

    @property
    def ok(self) -> bool:
        """Whether the joint has a trustworthy offset."""
        return self.code == "ok"

    def to_report(self) -> dict[str, Any]:
        """Plain values for a JSON report."""

        def deg(x: float) -> float | None:
            return None if not math.isfinite(x) else round(math.degrees(x), 4)

        return {
            "code": self.code,
            "reason": self.reason,
            "offset_rad": None if not math.isfinite(self.offset_rad) else self.offset_rad,
            "q_stop_minus_deg": None if self.lower is None else deg(self.lower.q_stop_rad),
            "q_stop_plus_deg": None if self.upper is None else deg(self.upper.q_stop_rad),
            "span_deg": deg(self.span_rad),
            "expected_span_deg": deg(self.expected_span_rad),
            "lower": None if self.lower is None else self.lower.to_report(),
            "upper": None if self.upper is None else self.upper.to_report(),
        }


def joint_zero(
    name: str,
    lower: StopResult | None,
    upper: StopResult | None,
    expected_lower_rad: float | None,
    expected_upper_rad: float | None,
    span_tol_rad: float = math.radians(5.0),
    stop_tol_rad: float = math.radians(10.0),
) -> JointStops:
    """Combine the stop searches of one joint into its offset (``q_joint = s − offset``).

    Two-sided (both results given): the midpoint of the measured contact surfaces lands on the midpoint of the
    expected stop angles, ``offset = ½(s⁻ + s⁺) − ½(lower + upper)``; the measured span must match
    ``upper − lower`` within ``span_tol_rad`` (an obstacle or a cable hit first, or a missing stop: span
    mismatch). One-sided: ``offset = s_stop − stop`` where ``stop`` is the profile's angle of that stop.

    Args:
        name: Joint name (for messages).
        lower: Result of the search into the lower stop, or None.
        upper: Result of the search into the upper stop, or None.
        expected_lower_rad: Expected lower stop angle (joint frame), or None.
        expected_upper_rad: Expected upper stop angle (joint frame), or None.
        span_tol_rad: Span plausibility tolerance.
        stop_tol_rad: One-sided: how far the raw stop may be from… (unused for two-sided); kept for reports.

    Raises:
        InvalidCalibrationError: No search given, or a one-sided search without its expected angle.
    """
    del stop_tol_rad
    if lower is None and upper is None:
        raise InvalidCalibrationError(f"joint {name}: no stop search to combine")
    for res in (lower, upper):
        if res is not None and not res.ok:
            side = "lower" if res.direction < 0 else "upper"
            return JointStops(name, res.code, f"{side} stop: {res.reason}", lower, upper, math.nan)
    if lower is not None and upper is not None:
        s_lo, s_hi = lower.q_stop_rad, upper.q_stop_rad
        span = s_hi - s_lo
        if expected_lower_rad is None or expected_upper_rad is None:
            return JointStops(
                name, "ok", "", lower, upper, 0.5 * (s_lo + s_hi), span_rad=span
            )  # no expectation: zero mid-range
        exp_span = expected_upper_rad - expected_lower_rad
        offset = 0.5 * (s_lo + s_hi) - 0.5 * (expected_lower_rad + expected_upper_rad)
        if abs(span - exp_span) > span_tol_rad:
            return JointStops(
                name,
                "span_mismatch",
                f"span {math.degrees(span):.1f}° differs from the expected {math.degrees(exp_span):.1f}° by more "
                f"than {math.degrees(span_tol_rad):.1f}° (an obstacle, a cable or a missing stop?)",
                lower,
                upper,
                math.nan,
                span,
                exp_span,
            )
        return JointStops(name, "ok", "", lower, upper, offset, span, exp_span)
    res = lower if lower is not None else upper
    assert res is not None
    expected = expected_lower_rad if res is lower else expected_upper_rad
    if expected is None:
        raise InvalidCalibrationError(f"joint {name}: a one-sided stop needs its expected angle")
    return JointStops(name, "ok", "", lower, upper, res.q_stop_rad - expected)


def with_gravity(config: SearchConfig, gravity_nm: Callable[[float], float] | None) -> SearchConfig:
    """``config`` with a gravity model (``τ_g(q)`` in the joint frame)."""
    return replace(config, gravity_nm=gravity_nm)


def summarise(values: Sequence[float]) -> tuple[float, float]:
    """Mean and standard deviation (ddof 0) of finite values; NaNs when none."""
    arr = np.asarray([v for v in values if math.isfinite(v)], dtype=float)
    if arr.size == 0:
        return math.nan, math.nan
    return float(arr.mean()), float(arr.std())
