"""Hard-stop sweep math: wrap-aware range tracking, the bisection rule and sweep diagnostics.

Pure numpy. Positions here are in the *identity frame* of a Robstride joint, ``s = direction·raw`` (rad): what
the robot publishes with an empty calibration file. The bisection rule puts the centre of the sampled range on
the centre of the URDF range::

    lower_offset  = s_min − lower            (joint frame, rad)
    upper_offset  = s_max − upper
    homing_offset = ½·(lower_offset + upper_offset)·direction     (motor frame, rad)

Diagnostic codes and the result values are in :mod:`robocal.core.sweep_result`.

The one-sided rule (Berkeley-Humanoid-Lite-Lowlevel ``scripts/calibrate_joints.py``) pushes each joint into one
stop only, whose joint angle ``stop`` is known, and keeps the extreme of ``s`` on that side::

    limit_reading   = min(s) (lower stop) or max(s) (upper stop)        (identity frame, rad)
    position_offset = limit_reading − stop                               (joint frame: q = s − position_offset)
    homing_offset   = direction·position_offset                         (motor frame, exact: direction is ±1)
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence

import numpy as np
import numpy.typing as npt

from ..errors import InvalidCalibrationError, ShapeMismatchError
from .arrays import FloatArray
from .sweep_result import (
    DEFAULT_SPAN_TOLERANCE_RAD,
    DEFAULT_THRESHOLD_RAD,
    WARNING_CODES,
    JointSweep,
    SweepResult,
)
from .wrap_range import RangeTracker

__all__ = [
    "DEFAULT_ONE_SIDED_THRESHOLD_RAD",
    "RangeTracker",
    "analyse_sweep",
    "bisect_homing_offset",
    "direction_from_motion",
    "one_sided_position_offset",
    "wrap_in_travel",
]


DEFAULT_ONE_SIDED_THRESHOLD_RAD = 0.05
"""One-sided procedure: a joint that moved less than this (rad) counts as not moved. A joint is only pushed
into one stop, often from close by (an ankle roll 0.26 rad from its stop), so the two-sided threshold is too big."""


def bisect_homing_offset(
    s_min: npt.ArrayLike,
    s_max: npt.ArrayLike,
    lower: npt.ArrayLike,
    upper: npt.ArrayLike,
    direction: npt.ArrayLike,
) -> FloatArray:
    """The bisection rule: motor-frame homing offset that centres the sampled range on the URDF range.

    Args:
        s_min: Sampled minimum, identity frame (``direction·raw``), shape ``(N,)``, rad.
        s_max: Sampled maximum, identity frame, shape ``(N,)``, rad.
        lower: URDF lower limit, shape ``(N,)``, rad.
        upper: URDF upper limit, shape ``(N,)``, rad.
        direction: ±1 per joint, shape ``(N,)``.

    Returns:
        ``homing_offset`` per joint, shape ``(N,)``, motor frame, rad.
    """
    lo_off = np.asarray(s_min, dtype=np.float64) - np.asarray(lower, dtype=np.float64)
    up_off = np.asarray(s_max, dtype=np.float64) - np.asarray(upper, dtype=np.float64)
    out: FloatArray = 0.5 * (lo_off + up_off) * np.asarray(direction, dtype=np.float64)
    return out


def wrap_in_travel(
    homing_offset: npt.ArrayLike,
    direction: npt.ArrayLike,
    lower: npt.ArrayLike,
    upper: npt.ArrayLike,
    zero_sta: npt.ArrayLike = 0,
) -> npt.NDArray[np.bool_]:
    """Whether each joint's raw travel contains the motor's power-on wrap point.

    The raw travel is ``homing_offset + direction·[lower, upper]``. With ``zero_sta`` 0 the power-on reading
    is in ``[0, 2π)`` (wrap points at ``2πk``); with ``zero_sta`` 1 it is in ``[−π, π)`` (wrap points at
    ``π + 2πk``).

    Args:
        homing_offset: Shape ``(N,)``, motor frame, rad.
        direction: Shape ``(N,)``, ±1.
        lower: Shape ``(N,)``, rad.
        upper: Shape ``(N,)``, rad.
        zero_sta: Shape ``(N,)`` or scalar, 0 or 1.

    Returns:
        Shape ``(N,)`` booleans.
    """
    h = np.asarray(homing_offset, dtype=np.float64)
    d = np.asarray(direction, dtype=np.float64)
    a = h + np.minimum(d * np.asarray(lower, dtype=np.float64), d * np.asarray(upper, dtype=np.float64))
    b = h + np.maximum(d * np.asarray(lower, dtype=np.float64), d * np.asarray(upper, dtype=np.float64))
    w = np.where(np.asarray(zero_sta) == 1, math.pi, 0.0)
    # a wrap point w + 2πk lies strictly inside (a, b) iff the next one above a is below b
    k = np.floor((a - w) / math.tau) + 1.0
    out: npt.NDArray[np.bool_] = np.isfinite(h) & (w + k * math.tau < b)
    return out


def direction_from_motion(delta_s_rad: float, min_motion_rad: float = 0.2) -> int:
    """Sign of a guided "move toward the + limit" step seen in the identity frame.

    Args:
        delta_s_rad: Change of ``direction·raw`` while the operator moved the joint toward its + limit, rad.
        min_motion_rad: Smallest change that counts as motion, rad.

    Returns:
        +1 when the URDF direction is right, −1 when it is flipped, 0 when the joint did not move enough.
    """
    if not math.isfinite(delta_s_rad) or abs(delta_s_rad) < min_motion_rad:
        return 0
    return 1 if delta_s_rad > 0 else -1


def one_sided_position_offset(
    sampled_min: npt.ArrayLike, sampled_max: npt.ArrayLike, stop: Sequence[str], stop_rad: npt.ArrayLike
) -> FloatArray:
    """The one-sided rule: ``limit_reading − stop_angle``, with the extreme on each joint's stop side.

    Args:
        sampled_min: Minimum of ``direction·raw``, shape ``(N,)``, rad.
        sampled_max: Maximum of ``direction·raw``, shape ``(N,)``, rad.
        stop: ``"lower"`` (keep the minimum) or ``"upper"`` (keep the maximum) per joint.
        stop_rad: Joint angle of that stop per joint, shape ``(N,)``, rad.

    Returns:
        Upstream's ``position_offsets`` per joint, joint frame, shape ``(N,)``, rad (``q = s − offset``);
        the homing offset is ``direction·offset``.
    """
    lo = np.asarray(sampled_min, dtype=np.float64)
    hi = np.asarray(sampled_max, dtype=np.float64)
    pick = np.array([side == "lower" for side in stop], dtype=bool)
    out: FloatArray = np.where(pick, lo, hi) - np.asarray(stop_rad, dtype=np.float64)
    return out


def _vec(x: npt.ArrayLike, n: int, what: str) -> FloatArray:
    arr = np.asarray(x, dtype=np.float64)
    if arr.ndim == 0:
        arr = np.full(n, float(arr))
    if arr.shape != (n,):
        raise ShapeMismatchError(f"analyse_sweep: {what} has shape {arr.shape}; expected ({n},)")
    return arr


def analyse_sweep(
    joint_names: Sequence[str],
    direction: npt.ArrayLike,
    lower: npt.ArrayLike,
    upper: npt.ArrayLike,
    sampled_min: npt.ArrayLike,
    sampled_max: npt.ArrayLike,
    *,
    prior: Mapping[str, float] | None = None,
    threshold_rad: float = DEFAULT_THRESHOLD_RAD,
    span_tolerance_rad: float = DEFAULT_SPAN_TOLERANCE_RAD,
    zero_sta: npt.ArrayLike = 0,
    direction_check: Mapping[str, int] | None = None,
    method: str = "two-sided",
    stops: Sequence[str | None] | None = None,
    stop_rad: npt.ArrayLike | None = None,
    first: npt.ArrayLike | None = None,
    wraps: bool = True,
) -> SweepResult:
    """Apply the bisection (or one-sided) rule and every diagnostic to a finished sweep.

    Args:
        joint_names: N joint names.
        direction: URDF direction per joint, shape ``(N,)``, ±1.
        lower: URDF lower limits, shape ``(N,)``, rad.
        upper: URDF upper limits, shape ``(N,)``, rad.
        sampled_min: Unwrapped minimum of ``direction·raw``, shape ``(N,)``, rad (NaN: no sample).
        sampled_max: Unwrapped maximum of ``direction·raw``, shape ``(N,)``, rad.
        prior: Prior homing offsets by joint name (motor frame, rad), kept for joints not swept.
        threshold_rad: Sweeps below this count as not swept.
        span_tolerance_rad: Allowed ``|sweep − (upper − lower)|``.
        zero_sta: Power-on range per joint (0: ``[0, 2π)``, 1: ``[−π, π)``), shape ``(N,)`` or scalar.
        direction_check: Result of the guided direction check per joint (+1 right, −1 flipped, 0 unknown).
            When given, a joint with 0 or no entry gets ``direction_unknown``; None: no check was run.
        method: ``two-sided`` (bisection) or ``one-sided`` (each joint's ``stops`` side and ``stop_rad``).
        stops: Per joint ``"lower"``, ``"upper"`` or None: the stop of the one-sided rule. With stops, a
            joint that reached both stops gets both rules in the report, whatever the method.
        stop_rad: Joint angle of each joint's stop, shape ``(N,)``, rad (NaN where none).
        first: First finite ``direction·raw`` per joint, shape ``(N,)``, rad: lets the one-sided rule see a
            joint that only moved away from its stop (``wrong_side``).
        wraps: Whether the position reading wraps each motor turn (``wrap_in_travel`` is checked only then).

    Returns:
        The :class:`SweepResult`.
    """
    names = tuple(joint_names)
    n = len(names)
    d = _vec(direction, n, "direction")
    lo = _vec(lower, n, "lower")
    up = _vec(upper, n, "upper")
    smin = _vec(sampled_min, n, "sampled_min")
    smax = _vec(sampled_max, n, "sampled_max")
    zs = np.broadcast_to(np.asarray(zero_sta), (n,))
    if not (math.isfinite(threshold_rad) and threshold_rad >= 0):
        raise InvalidCalibrationError(f"threshold {threshold_rad} must be a finite number >= 0 rad")
    if not (math.isfinite(span_tolerance_rad) and span_tolerance_rad >= 0):
        raise InvalidCalibrationError(f"span tolerance {span_tolerance_rad} must be a finite number >= 0 rad")
    if method not in ("one-sided", "two-sided"):
        raise InvalidCalibrationError(f"method {method!r}: expected one-sided or two-sided")
    side = list(stops) if stops is not None else [None] * n
    if len(side) != n:
        raise ShapeMismatchError(f"analyse_sweep: stops has {len(side)} entries; expected {n}")
    bad = [names[i] for i, x in enumerate(side) if x not in (None, "lower", "upper")]
    if bad:
        raise InvalidCalibrationError(f"analyse_sweep: stop of {', '.join(bad)} must be lower, upper or None")
    angle = _vec(np.nan if stop_rad is None else stop_rad, n, "stop_rad")
    if method == "one-sided":
        lacking = [names[i] for i in range(n) if side[i] is None or not math.isfinite(angle[i])]
        if lacking:
            raise InvalidCalibrationError(
                f"the one-sided rule needs a stop and its angle for every joint; none for {', '.join(lacking)}"
            )
    start = _vec(np.nan if first is None else first, n, "first")
    prior = dict(prior or {})
    checks = dict(direction_check or {})
    sweep = np.where(np.isfinite(smin) & np.isfinite(smax), smax - smin, 0.0)
    h_bis = bisect_homing_offset(smin, smax, lo, up, d)
    p_off = one_sided_position_offset(smin, smax, [x or "lower" for x in side], angle)
    joints: list[JointSweep] = []
    for i, name in enumerate(names):
        warnings: set[str] = set()
        prev = prior.get(name)
        prev_f = None if prev is None else float(prev)
        both = bool(sweep[i] >= (up[i] - lo[i]) - span_tolerance_rad)
        has_stop = side[i] is not None and math.isfinite(angle[i])
        swept = bool(sweep[i] >= threshold_rad and np.isfinite(h_bis[i]))
        pos_off = float(p_off[i]) if has_stop and swept else math.nan
        h_one = float(d[i] * pos_off)
        if not swept:
            warnings.add("not_swept")
            h = prev_f if prev_f is not None else math.nan
            kept = prev_f is not None
            bis = math.nan
        elif method == "one-sided":
            h = h_one
            bis = float(h_bis[i])
            kept = False
            q_lo, q_hi = smin[i] - pos_off, smax[i] - pos_off  # the sampled range in the new joint frame
            if (side[i] == "lower" and q_hi > up[i] + span_tolerance_rad) or (
                side[i] == "upper" and q_lo < lo[i] - span_tolerance_rad
            ):
                warnings.add("span_mismatch")  # the joint went past the URDF's other limit
            if abs(h) > math.pi:
                warnings.add("offset_large")
            if math.isfinite(start[i]) and not both:  # a joint that reached both stops went to its own, too
                toward = start[i] - smin[i] if side[i] == "lower" else smax[i] - start[i]
                away = smax[i] - start[i] if side[i] == "lower" else start[i] - smin[i]
                if away >= threshold_rad and toward < 0.1 * threshold_rad:
                    warnings.add("wrong_side")
        else:
            h = float(h_bis[i])
            bis = h
            kept = False
            if smin[i] > up[i] or smax[i] < lo[i]:
                warnings.add("no_overlap")
            if abs(sweep[i] - (up[i] - lo[i])) > span_tolerance_rad:
                warnings.add("span_mismatch")
            if abs(h) > math.pi:
                warnings.add("offset_large")
        if wraps and math.isfinite(h) and bool(wrap_in_travel(h, d[i], lo[i], up[i], zs[i])):
            warnings.add("wrap_in_travel")
        if direction_check is not None:
            verdict = checks.get(name, 0)
            if verdict < 0:
                warnings.add("direction_flipped")
            elif verdict == 0:
                warnings.add("direction_unknown")
        joints.append(
            JointSweep(
                name=name,
                direction=int(d[i]),
                lower=float(lo[i]),
                upper=float(up[i]),
                sampled_min=float(smin[i]),
                sampled_max=float(smax[i]),
                sweep=float(sweep[i]),
                homing_offset=float(h),
                bisection_offset=float(bis),
                previous_homing_offset=prev_f,
                kept_prior=kept,
                warnings=tuple(c for c in WARNING_CODES if c in warnings),
                zero_sta=int(zs[i]),
                method=method,
                stop=side[i],
                stop_angle=float(angle[i]),
                position_offset=pos_off,
                one_sided_offset=h_one,
                both_stops=both and swept,
            )
        )
    return SweepResult(tuple(joints), float(threshold_rad), float(span_tolerance_rad))
