"""Values of the automatic hard-stop search: configuration, readings, commands, results (see stop_search)."""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

from ..errors import InvalidCalibrationError

__all__ = [
    "EVIDENCE_GAP_S",
    "FAIL_CODES",
    "TESTS",
    "CodedOutcome",
    "Command",
    "SearchConfig",
    "StopResult",
    "StopSample",
    "report_deg",
    "report_num",
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
EVIDENCE_GAP_S = 0.1
"""A reading's interval counts at most this long toward a stop search's or a move's dwells and time bound
(:attr:`SearchConfig.evidence_gap_s`): what a joint did while robocal was held up is unknown."""

TESTS = ("torque", "lag", "overload+reread", "no-reply+reread", "transit-stall", "blocked")
"""Which test declared the stop."""


class CodedOutcome:
    """Mixin of a search outcome with a ``code`` (``ok`` or one of :data:`FAIL_CODES`) and a ``reason``."""

    code: str
    reason: str

    @property
    def ok(self) -> bool:
        """Whether the code is ``ok`` (the stop was found; the joint has a trustworthy offset)."""
        return self.code == "ok"

    def _report_code(self) -> dict[str, Any]:
        """The first keys of a JSON report: code and reason."""
        return {"code": self.code, "reason": self.reason}


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
        max_reading_gap_s: A reading that comes more than this after the one before while the joint is driven fails
            the search (``no_reply``); None: ``reply_timeout_s``; ``math.inf``: never, for a driver whose motor has a
            host-loss watchdog it arms and whose trip it reports as a fault (a Damiao motor: robocal held up for less
            than the watchdog left the motor under its last command, its target within ``max_lag_rad`` of the
            joint, so the reading after the gap is evidence like any other; held up for longer, the motor stopped
            itself and the next reading says so).
        evidence_gap_s: A reading that comes more than this after the one before counts only this long toward a
            dwell (the stall and blocked tests) and the time bound: what the joint did while robocal was held up
            is unknown, so a scheduling gap neither confirms a stop nor uses up the search's time.
        max_suspects: Unconfirmed suspect events allowed at one place before the search fails (a good reading more
            than ``2·confirm_tol_rad`` from the last one's re-read starts the count again: on a busy host replies
            come late all along the travel).
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
    max_reading_gap_s: float | None = None
    max_suspects: int = 3
    evidence_gap_s: float = EVIDENCE_GAP_S
    gravity_nm: Callable[[float], float] | None = field(default=None, compare=False)

    def __post_init__(self) -> None:
        for name in (
            "speed_rad_s",
            "torque_cap_nm",
            "max_travel_rad",
            "max_time_s",
            "max_lag_rad",
            "dwell_s",
            "evidence_gap_s",
        ):
            value = getattr(self, name)
            if not (isinstance(value, (int, float)) and math.isfinite(value) and value > 0):
                raise InvalidCalibrationError(
                    f"stop search: {name} must be a positive finite number, got {value!r}"
                )
        gap = self.max_reading_gap_s
        if gap is not None and not (isinstance(gap, (int, float)) and gap > 0 and not math.isnan(gap)):
            raise InvalidCalibrationError(f"stop search: max_reading_gap_s must be None or > 0, got {gap!r}")
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
class StopSample:
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
class StopResult(CodedOutcome):
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

    def to_report(self) -> dict[str, Any]:
        """Plain values for a JSON report (degrees where a person reads them)."""
        return {
            **self._report_code(),
            "q_stop_deg": report_deg(self.q_stop_rad),
            "q_pressed_deg": report_deg(self.q_pressed_rad),
            "detection_torque_nm": report_num(self.torque_nm),
            "stiffness_nm_per_rad": report_num(self.stiffness_nm_per_rad, 2),
            "test": self.test,
            "t_detect_s": report_num(self.t_detect_s, 3),
            "duration_s": report_num(self.duration_s, 3),
            "travel_deg": report_deg(self.travel_rad),
            "peak_torque_nm": report_num(self.peak_torque_nm),
            "touches_deg": [report_deg(x) for x in self.touches],
        }


def report_deg(x_rad: float) -> float | None:
    """An angle for a JSON report: degrees to 4 decimals, None when not finite (not measured)."""
    return None if not math.isfinite(x_rad) else round(math.degrees(x_rad), 4)


def report_num(x: float, nd: int = 4) -> float | None:
    """A number for a JSON report: ``nd`` decimals, None when not finite (not measured)."""
    return None if not math.isfinite(x) else round(x, nd)
