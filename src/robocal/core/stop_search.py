"""Automatic hard-stop search: a backend-neutral state machine and the per-joint zero/span math.

Pure numpy, no I/O, no clock: a driver (a Robstride MIT loop, a Feetech or Dynamixel servo, a simulator)
feeds :class:`StopSample` values — time, position, velocity, torque, flags — into :meth:`StopSearch.step` and
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
* **Evidence under load.** The lag test measures how far the joint is short of the target it had a whole
  control period to reach (the one sent before the last), never of the target just advanced by the time since
  the last reading: after a scheduling gap that target leads by ``speed·gap`` (up to ``max_lag_rad``) although
  the joint followed every command, so a slow loop looked held back (issue 26 item 4: the SO-101's and Koch's
  stops found in free travel under CPU load). The dwells (stall, blocked) and the time bound run on a clock
  that counts each reading's interval at most ``evidence_gap_s``: a gap neither confirms a stop nor uses up
  the search's time.
* **Suspect evidence.** An overload flag or a lost reply never declares a stop by itself: the search asks for a
  re-read (``Command.action == "reread"``: clear the latch, read the position). After an overload, if the joint
  was armed and slow and the re-read position agrees with the last good one within ``confirm_tol_rad``, the stop
  is confirmed (test ``overload+reread``). A lost reply is no evidence of a push at all (on a busy host a reply
  comes late while a joint following its target stick-slip happens to rest): its agreeing re-read only marks the
  place, the joint is driven ``2·confirm_tol_rad`` past it, and only a further lost reply whose re-read finds it
  still there confirms the stop (``no-reply+reread``: a motor silent while it presses). Otherwise the approach
  continues (at most ``max_suspects`` times). Replies missing for longer than ``reply_timeout_s`` fail the search
  (``no_reply``), and so does a reading that comes more than ``max_reading_gap_s`` (default ``reply_timeout_s``)
  after the one before while the joint is driven (the host was descheduled or the reply was late: a fault, the
  joint limp, never a missed stop; issue 26). A driver whose motor's own host-loss watchdog decides (Damiao) sets
  no such bound: the reading after the gap says whether the motor stopped itself.
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
from dataclasses import replace

import numpy as np

from ..errors import InvalidCalibrationError
from .stop_types import EVIDENCE_GAP_S, FAIL_CODES, TESTS, Command, SearchConfig, StopResult, StopSample
from .stop_zero import JointStops, joint_zero, summarise, with_gravity

__all__ = ["EVIDENCE_GAP_S", "FAIL_CODES", "TESTS", "Command", "JointStops", "SearchConfig", "StopResult",
           "StopSample", "StopSearch", "joint_zero", "summarise", "with_gravity"]  # fmt: skip

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
        self._given = math.nan  # the target of the command before the last (the joint had a period to reach it)
        self._counted_s = 0.0  # time since the start, each reading's interval counted at most evidence_gap_s
        self._armed = False
        self._stall_since: float | None = None
        self._blocked_since: float | None = None
        self._window: list[StopSample] = []
        self._last_good: StopSample | None = None
        self._no_reply_since: float | None = None
        self._suspects = 0
        self._probe_q: float | None = None  # a lost reply's re-read position the joint was then driven past
        self._suspect_q: float | None = None  # where the last unconfirmed suspect was re-read
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

    def start(self, sample: StopSample) -> Command:
        """Begin at the joint's current reading (must be a good reply)."""
        if not sample.ok or not math.isfinite(sample.q_rad):
            return self._fail("no_reply", "no position reading at the start of the search", sample)
        self._t0 = self._t_last = sample.t_s
        self._q0 = self._touch_start_q = sample.q_rad
        self._target = self._given = sample.q_rad
        self._last_good = sample
        return self._drive_cmd()

    def abort(self, reason: str = "aborted") -> StopResult:
        """End the search now (Ctrl-C, a fault elsewhere): the result is ``aborted``."""
        if self._result is None:
            self._result = self._make_fail("aborted", reason)
        return self._result

    def step(self, sample: StopSample) -> Command:
        """Feed the next reading; returns the next command (``hold`` or ``limp`` once done)."""
        cfg = self.config
        if self._result is not None:
            return self._final_cmd()
        dt = sample.t_s - self._t_last if math.isfinite(self._t_last) else 0.0
        self._t_last = sample.t_s
        self._counted_s += min(max(dt, 0.0), cfg.evidence_gap_s)
        gap_s = cfg.reply_timeout_s if cfg.max_reading_gap_s is None else cfg.max_reading_gap_s
        if dt > gap_s and self._phase in (_APPROACH, _PRESS_HI, _PRESS_LO, _BACKOFF):
            # the host was held up (descheduled, a reply that came late): what the joint did in between is
            # unknown, so the reading is not evidence of a stop or of free travel; a fault, never a missed stop
            return self._fail(
                "no_reply",
                f"a reading came {dt:.2f} s after the one before (more than {gap_s:.2f} s: robocal "
                "was held up or the reply was late)",
                sample,
            )
        if self._counted_s > cfg.max_time_s:
            if not sample.ok or not math.isfinite(sample.q_rad):  # silent at the bound: the device, not the stop
                return self._fail(
                    "no_reply",
                    f"no reply from the motor at the time bound {cfg.max_time_s:.1f} s (the device is lost or "
                    "not answering)",
                    sample,
                )
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
            # the evidence stays the reading before the flag: once the latch has cut the torque, the joint
            # springs back off the stop, and that motion says nothing about whether it was at rest there
            if self._last_good is None:
                self._last_good = sample
            return self._suspect("overload")
        self._last_good = sample
        if self._probe_q is not None and abs(sample.q_rad - self._probe_q) > cfg.confirm_tol_rad:
            self._probe_q = None  # it moved on from where a reply went missing: that was no stop
        if self._suspect_q is not None and abs(sample.q_rad - self._suspect_q) > 2.0 * cfg.confirm_tol_rad:
            self._suspects, self._suspect_q = 0, None  # max_suspects counts events at one place, not a busy host's
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

    def _approach(self, s: StopSample, dt: float) -> Command:
        cfg, d = self.config, self.direction
        # how far the joint is short of the target it had a whole period to reach (module docstring)
        lag = d * (self._given - s.q_rad)
        self._given = self._target
        self._target += d * cfg.speed_rad_s * max(dt, 0.0)
        lead = d * (self._target - s.q_rad)
        clamped = abs(lead) > cfg.max_lag_rad
        if clamped:  # ahead of the joint by at most max_lag, and never behind it by more
            self._target = s.q_rad + math.copysign(cfg.max_lag_rad, lead) * d
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
        torque_hit = math.isfinite(s.torque_nm) and d * s.torque_nm >= cfg.torque_fraction * cfg.torque_cap_nm
        lag_hit = lag >= cfg.lag_fraction * cfg.max_lag_rad
        if not self._armed and slow and (torque_hit or lag_hit):
            # held at the full push before the test could arm: something blocks the joint right here
            if self._blocked_since is None:
                self._blocked_since = self._counted_s
            elif self._counted_s - self._blocked_since >= 2 * cfg.dwell_s:
                self._result = replace(
                    self._make_fail(
                        "blocked",
                        f"blocked {math.degrees(abs(s.q_rad - self._touch_start_q)):.1f}° after the start, "
                        "before the stall test could arm",
                        s,
                    ),
                    q_pressed_rad=s.q_rad,
                )
                self._phase = _DONE
                return Command("limp")
        else:
            self._blocked_since = None
        if self._armed and slow and (torque_hit or lag_hit):
            if self._stall_since is None:
                self._stall_since = self._counted_s
                self._window = []
            self._window.append(s)
            if self._counted_s - self._stall_since >= cfg.dwell_s:
                test = "torque" if torque_hit else "lag"
                return self._contact(s, test)
        else:
            self._stall_since = None
            self._window = []
        return Command("drive", self._target, 0.0 if clamped else d * cfg.speed_rad_s, cfg.torque_cap_nm)

    def _contact(self, s: StopSample, test: str) -> Command:
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

    def _press(self, s: StopSample) -> Command:
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

    def _start_backoff(self, s: StopSample) -> Command:
        cfg = self.config
        self._phase = _BACKOFF
        self._phase_t0 = s.t_s
        self._backoff_goal = self._touches[-1] - self.direction * cfg.backoff_rad
        self._target = s.q_rad
        return Command("drive", s.q_rad, 0.0, cfg.torque_cap_nm)

    def _backoff(self, s: StopSample) -> Command:
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
                self._target = self._given = s.q_rad
                self._probe_q = None
                return self._drive_cmd()
            return self._finish(s)
        return Command(
            "drive", self._target, -d * cfg.speed_rad_s if remaining > 0 else 0.0, cfg.torque_cap_nm
        )

    def _finish(self, s: StopSample) -> Command:
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

    def _confirm(self, s: StopSample) -> Command:
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
        probing = resume == _APPROACH and self._suspect_kind == "no-reply" and self._armed and slow and agrees
        if probing and not self._probed(s):
            # a lost reply is no evidence: drive the joint on from here and ask again (see _probed)
            self._suspects += 1
            self._last_good = s
            self._probe_q = self._suspect_q = s.q_rad
            self._stall_since = None
            self._target = self._given = s.q_rad + self.direction * min(cfg.max_lag_rad, 2.0 * cfg.confirm_tol_rad)
            return Command("drive", self._target, 0.0, cfg.torque_cap_nm)
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
        self._last_good, self._suspect_q = s, s.q_rad
        if self._suspects > cfg.max_suspects:
            return self._fail(
                "no_reply" if self._suspect_kind == "no-reply" else "blocked",
                f"{self._suspects} {self._suspect_kind} events the position re-read did not confirm as a stop",
                s,
            )
        self._stall_since = None
        self._target = self._given = s.q_rad
        return self._drive_cmd()

    def _probed(self, s: StopSample) -> bool:
        """Whether a lost reply's re-read ``s`` confirms a stop: the joint was driven past this point and stayed.

        An overload flag is the motor's own evidence of a push; a lost reply is none. On a busy host a reply comes
        late while the joint, following its target in stick-slip steps, happens to be at rest, and its re-read
        agrees with the last good reading: the soak's OpenArm gripper had a stop "confirmed" that way 24° short of
        the true one (``span_mismatch``). So the first such re-read only marks the place (``_probe_q``); the joint
        is then driven on with a target ``2·confirm_tol`` (at most ``max_lag``) beyond it, and only a further lost
        reply whose re-read finds it still within ``confirm_tol`` of that place confirms the stop: the joint did
        not follow a target it could follow in free travel.
        """
        return self._probe_q is not None and abs(s.q_rad - self._probe_q) <= self.config.confirm_tol_rad

    # -- ends ---------------------------------------------------------------------------------------------
    def _make_fail(self, code: str, reason: str, s: StopSample | None = None) -> StopResult:
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

    def _fail(self, code: str, reason: str, s: StopSample) -> Command:
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
