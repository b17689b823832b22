"""A joint's zero and span from its stop searches (two-sided midpoint, one-sided stop angle, plausibility)."""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from ..errors import InvalidCalibrationError
from .stop_types import CodedOutcome, SearchConfig, StopResult, report_deg

__all__ = ["JointStops", "gravity_corrected", "joint_zero", "summarise", "with_gravity"]


@dataclass(frozen=True)
class JointStops(CodedOutcome):
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

    def to_report(self) -> dict[str, Any]:
        """Plain values for a JSON report."""
        return {
            **self._report_code(),
            "offset_rad": None if not math.isfinite(self.offset_rad) else self.offset_rad,
            "q_stop_minus_deg": None if self.lower is None else report_deg(self.lower.q_stop_rad),
            "q_stop_plus_deg": None if self.upper is None else report_deg(self.upper.q_stop_rad),
            "span_deg": report_deg(self.span_rad),
            "expected_span_deg": report_deg(self.expected_span_rad),
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
    gravity: Callable[[float], float] | None = None,
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
        gravity: The joint's gravity torque ``τ_g(q)`` in the joint (URDF) frame, e.g. a
            :class:`~robocal.core.gravity.JointGravity` from the URDF: each stop is corrected by
            :func:`gravity_corrected` before the midpoint and the span.

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
    if gravity is not None:
        lower, upper = gravity_corrected(lower, upper, expected_lower_rad, expected_upper_rad, gravity)
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


def _offset(
    lower: StopResult | None, upper: StopResult | None, exp_lo: float | None, exp_hi: float | None
) -> float:
    """The offset :func:`joint_zero` would give (``q_joint = s − offset``), without any check."""
    if lower is not None and upper is not None:
        mid = 0.5 * (lower.q_stop_rad + upper.q_stop_rad)
        return mid if exp_lo is None or exp_hi is None else mid - 0.5 * (exp_lo + exp_hi)
    res = lower if lower is not None else upper
    expected = exp_lo if res is lower else exp_hi
    assert res is not None
    return res.q_stop_rad - (0.0 if expected is None else expected)


def gravity_corrected(
    lower: StopResult | None,
    upper: StopResult | None,
    expected_lower_rad: float | None,
    expected_upper_rad: float | None,
    gravity: Callable[[float], float],
    iterations: int = 3,
) -> tuple[StopResult | None, StopResult | None]:
    """The stops with the gravity sink removed: ``q_stop − τ_g(q_joint)/k̂`` for each stop.

    A stop of stiffness ``k`` pressed by the motor and by gravity sits at ``q = q_surface + (τ + τ_g)/k``; the
    search removed the motor's part (``τ/k̂``). Gravity is known in the joint (URDF) frame, while the stops are
    in the driver's frame ``s = q_joint + offset`` with the offset not known yet: it is estimated from the stops
    (the midpoint rule, or the one-sided stop angle), the stops are corrected at ``q_joint = s − offset``, and
    that is repeated ``iterations`` times (the offset moves by ``τ_g/k``, a small angle, so it converges at once).

    A stop without a stiffness estimate (NaN, e.g. a ``transit-stall``) is left as it is.

    Args:
        lower: Lower-stop result (ok) or None.
        upper: Upper-stop result (ok) or None.
        expected_lower_rad: Expected lower stop angle (joint frame) or None.
        expected_upper_rad: Expected upper stop angle or None.
        gravity: ``τ_g(q_joint)``, N·m, positive towards +q.
        iterations: Fixed-point iterations of the offset.

    Returns:
        ``(lower, upper)`` with corrected ``q_stop_rad``.
    """
    originals = (lower, upper)
    corrected = originals
    for _ in range(max(1, iterations)):
        offset = _offset(*corrected, expected_lower_rad, expected_upper_rad)
        new: list[StopResult | None] = []
        for res, cur in zip(originals, corrected, strict=True):
            k = math.nan if res is None else res.stiffness_nm_per_rad
            if res is None or cur is None or not (math.isfinite(k) and k > 0):
                new.append(res)
                continue
            tau_g = float(gravity(cur.q_stop_rad - offset))  # the surface in the joint frame
            new.append(replace(res, q_stop_rad=res.q_stop_rad - tau_g / k))
        corrected = (new[0], new[1])
    return corrected


def with_gravity(config: SearchConfig, gravity_nm: Callable[[float], float] | None) -> SearchConfig:
    """``config`` with a gravity model (``τ_g(q)`` in the joint frame)."""
    return replace(config, gravity_nm=gravity_nm)


def summarise(values: Sequence[float]) -> tuple[float, float]:
    """Mean and standard deviation (ddof 0) of finite values; NaNs when none."""
    arr = np.asarray([v for v in values if math.isfinite(v)], dtype=float)
    if arr.size == 0:
        return math.nan, math.nan
    return float(arr.mean()), float(arr.std())
