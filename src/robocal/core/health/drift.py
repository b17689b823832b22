"""How far a stored calibration has drifted from the stops found again (``--auto --verify``), pure math.

Two shapes of stored calibration: a LeRobot arm's (a range in the motor's ticks: both ends compared,
:func:`range_drift`) and a joint map's homing offset (``q = direction·(raw − homing_offset)``: the offset the stops
give now against the stored one, :func:`offset_drift`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

__all__ = ["JointDrift", "offset_drift", "range_drift"]


@dataclass(frozen=True)
class JointDrift:
    """How far one joint's stored calibration has drifted from its stops.

    Attributes:
        name: Joint (motor) name.
        drift_deg: How much more the joint reads now, with the stored calibration, at the same physical place
            than when it was calibrated, degrees (the stops' middle now minus where the calibration has it).
        uncertainty_deg: The measurement's uncertainty (±), degrees.
        lower_deg: The lower stop's shift, degrees (NaN where the stored calibration has no stops to compare).
        upper_deg: The upper stop's shift, degrees (NaN likewise).
        flagged: ``|drift_deg|`` is above the tolerance.
    """

    name: str
    drift_deg: float
    uncertainty_deg: float
    lower_deg: float
    upper_deg: float
    flagged: bool


def _wrapped(delta: float, turn: float) -> float:
    half = turn / 2
    return (delta + half) % turn - half


def range_drift(
    name: str,
    found_rad: tuple[float, float],
    stored_ticks: tuple[float, float],
    resolution: int,
    tolerance_deg: float,
) -> JointDrift:
    """The drift of a stored range: the stops found against the stored ends.

    ``found_rad``: the driver's unwrapped frame, rad; ``stored_ticks``: the motor's actual ticks, modulo a turn.
    The drift is the shift of the middle, ``((lo_found − lo_stored) + (hi_found − hi_stored)) / 2``; the
    uncertainty ``hypot((Δhi − Δlo)/2, one count)`` (ends that moved differently: a span that changed, not an
    offset). A stored range of a whole turn (LeRobot's full-turn joints) is not its stops: only its middle is
    compared, ± one count.
    """
    per_deg = resolution / 360.0
    lo_t, hi_t = (q * resolution / (2 * math.pi) for q in found_rad)
    d_lo = _wrapped(lo_t - stored_ticks[0], resolution) / per_deg
    d_hi = _wrapped(hi_t - stored_ticks[1], resolution) / per_deg
    drift = 0.5 * (d_lo + d_hi)
    count = 360.0 / resolution
    if stored_ticks[1] - stored_ticks[0] >= resolution - 1:
        return JointDrift(name, drift, count, math.nan, math.nan, abs(drift) > tolerance_deg)
    uncertainty = math.hypot(0.5 * (d_hi - d_lo), count)
    return JointDrift(name, drift, uncertainty, d_lo, d_hi, abs(drift) > tolerance_deg)


def offset_drift(
    name: str,
    direction: int,
    offset_found_rad: float,
    offset_stored_rad: float,
    span_error_rad: float,
    resolution_rad: float,
    tolerance_deg: float,
) -> JointDrift:
    """The drift of a stored homing offset (``q = direction·(raw − homing_offset)``).

    With the stored offset the joint reads ``direction·(offset_found − offset_stored)`` more than with the one
    the stops give now (modulo a turn). Uncertainty: ``hypot(span_error/2, resolution)``, the found span's
    distance from the expected one halved (a stop that is not where the profile expects moves the middle) and one
    count of the encoder.
    """
    drift = math.degrees(direction * _wrapped(offset_found_rad - offset_stored_rad, 2 * math.pi))
    uncertainty = math.degrees(math.hypot(0.5 * span_error_rad, resolution_rad))
    return JointDrift(name, drift, uncertainty, math.nan, math.nan, abs(drift) > tolerance_deg)
