"""The outcome of a hard-stop sweep: per-joint and per-robot results, warning codes and their explanations.

Pure numpy. Sampled values are in the *identity frame* of a joint, ``s = direction·raw`` (rad); offsets in the
motor frame (see :mod:`robocal.core.sweep` for the rules that compute them).

Diagnostic codes (stable, used in reports and the live view):

* ``ok`` — nothing to report.
* ``not_swept`` — sweep below the threshold; the prior offset is kept (no prior: the joint has no offset).
* ``no_overlap`` — the sampled range and the URDF range do not overlap (direction probably flipped).
* ``span_mismatch`` — ``|sweep − (upper − lower)|`` is above the tolerance (a stop is not where the URDF says,
  or the sweep stopped short).
* ``offset_large`` — ``|homing_offset| > π``.
* ``wrap_in_travel`` — the joint's raw travel contains the motor's power-on wrap point, so after a power cycle
  the raw reading can be off by 2π; :meth:`robocal.core.RobotCalibration.unwrap_to_limits` fixes it at load.
* ``direction_flipped`` — the guided direction check saw the joint move the wrong way.
* ``direction_unknown`` — the guided direction check ran but the joint did not move enough within its time, so
  its direction was not verified.
* ``wrong_side`` — one-sided procedure: the joint moved away from the stop it is to be pushed into and never
  went past its first reading toward that stop (the other stop was reached: direction flipped, or the wrong stop).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

from .named import get_named

__all__ = [
    "CODES",
    "DEFAULT_SPAN_TOLERANCE_RAD",
    "DEFAULT_THRESHOLD_RAD",
    "WARNING_CODES",
    "JointSweep",
    "SweepResult",
    "explain_warning",
]

DEFAULT_THRESHOLD_RAD = 0.5
"""A joint swept less than this (rad) counts as not swept (the upstream tool's default)."""
DEFAULT_SPAN_TOLERANCE_RAD = 0.15
"""Allowed difference between the sweep and the URDF span (rad)."""

WARNING_CODES: tuple[str, ...] = (
    "not_swept",
    "no_overlap",
    "span_mismatch",
    "offset_large",
    "wrap_in_travel",
    "direction_flipped",
    "direction_unknown",
    "wrong_side",
)
"""Every warning code, in display order."""
CODES: tuple[str, ...] = ("ok", *WARNING_CODES)
"""Every status code."""


@dataclass(frozen=True)
class JointSweep:
    """Sweep outcome of one joint (angles in rad; sampled values in the identity frame ``direction·raw``).

    Attributes:
        name: Joint name.
        direction: ±1 from the URDF.
        lower: URDF lower limit, rad.
        upper: URDF upper limit, rad.
        sampled_min: Unwrapped minimum of ``direction·raw`` (NaN when no sample arrived).
        sampled_max: Unwrapped maximum of ``direction·raw``.
        sweep: ``sampled_max − sampled_min``.
        homing_offset: The offset to write, motor frame (the prior's when not swept; NaN when there is none).
        bisection_offset: The bisection rule's offset (NaN when not swept).
        previous_homing_offset: The prior offset, or ``None``.
        kept_prior: True when the prior offset was kept because the joint was not swept.
        warnings: Warning codes, in :data:`WARNING_CODES` order.
        zero_sta: Power-on range of the motor (0: ``[0, 2π)``, 1: ``[−π, π)``), for :func:`explain_warning`.
        method: ``one-sided`` or ``two-sided``: the rule that gave :attr:`homing_offset`.
        stop: The stop of the one-sided rule (``lower``/``upper``), or None when the joint has none.
        stop_angle: Joint angle of that stop, rad (NaN when none).
        position_offset: The one-sided rule's joint-frame offset ``limit_reading − stop`` (upstream's
            ``position_offsets`` entry; NaN when not swept or no stop).
        one_sided_offset: The one-sided rule's homing offset ``direction·position_offset`` (NaN when none).
        both_stops: True when the sweep reached both stops (within the span tolerance), so both rules apply.
    """

    name: str
    direction: int
    lower: float
    upper: float
    sampled_min: float
    sampled_max: float
    sweep: float
    homing_offset: float
    bisection_offset: float
    previous_homing_offset: float | None
    kept_prior: bool
    warnings: tuple[str, ...]
    zero_sta: int = 0
    method: str = "two-sided"
    stop: str | None = None
    stop_angle: float = math.nan
    position_offset: float = math.nan
    one_sided_offset: float = math.nan
    both_stops: bool = False

    @property
    def status(self) -> str:
        """``"ok"`` or the first warning code."""
        return self.warnings[0] if self.warnings else "ok"

    @property
    def span(self) -> float:
        """URDF span ``upper − lower``, rad."""
        return self.upper - self.lower

    @property
    def has_offset(self) -> bool:
        """Whether :attr:`homing_offset` is a usable number."""
        return math.isfinite(self.homing_offset)

    @property
    def rule_difference(self) -> float:
        """Both stops reached: joint angle by the one-sided rule minus by the bisection rule, rad, else NaN.

        ``direction·(bisection_offset − one_sided_offset)``, the same at every reading: how far the one-sided
        stop angle (or the URDF limits) is off as this sweep sees it. NaN unless both rules have a value.
        """
        if not (
            self.both_stops and math.isfinite(self.one_sided_offset) and math.isfinite(self.bisection_offset)
        ):
            return math.nan
        return float(self.direction * (self.bisection_offset - self.one_sided_offset))

    def to_report(self) -> dict[str, Any]:
        """The joint's entry of the sweep report (JSON-ready; NaN becomes ``None``)."""

        def num(x: float | None) -> float | None:
            return None if x is None or not math.isfinite(x) else float(x)

        out: dict[str, Any] = {
            "sampled_min": num(self.sampled_min),
            "sampled_max": num(self.sampled_max),
            "sweep": num(self.sweep),
            "homing_offset": num(self.homing_offset),
            "previous_homing_offset": num(self.previous_homing_offset),
            "kept_prior": self.kept_prior,
            "warnings": list(self.warnings),
        }
        if self.method == "one-sided" or self.stop is not None:
            out["method"] = self.method
        if self.stop is not None:
            out["stop"] = self.stop
            out["stop_angle"] = num(self.stop_angle)
            out["position_offset"] = num(self.position_offset)
        if self.both_stops and math.isfinite(self.rule_difference):
            out["rules"] = {
                "one_sided_homing_offset": num(self.one_sided_offset),
                "two_sided_homing_offset": num(self.bisection_offset),
                "difference": num(self.rule_difference),
            }
        return out


@dataclass(frozen=True)
class SweepResult:
    """Sweep outcome of a whole robot.

    Attributes:
        joints: One :class:`JointSweep` per joint, in URDF order.
        threshold_rad: The not-swept threshold used, rad.
        span_tolerance_rad: The span tolerance used, rad.
    """

    joints: tuple[JointSweep, ...]
    threshold_rad: float = DEFAULT_THRESHOLD_RAD
    span_tolerance_rad: float = DEFAULT_SPAN_TOLERANCE_RAD

    @property
    def joint_names(self) -> tuple[str, ...]:
        """Joint names in order."""
        return tuple(j.name for j in self.joints)

    def __getitem__(self, name: str) -> JointSweep:
        return get_named(self.joints, name)

    @property
    def ok(self) -> bool:
        """True when no joint raised a warning."""
        return all(not j.warnings for j in self.joints)

    @property
    def missing_offsets(self) -> tuple[str, ...]:
        """Joints with no usable offset (not swept and no prior)."""
        return tuple(j.name for j in self.joints if not j.has_offset)

    def offsets(self) -> dict[str, float]:
        """Joint name → homing offset to write (joints without one are left out), motor frame, rad."""
        return {j.name: j.homing_offset for j in self.joints if j.has_offset}

    def explain(self, name: str, code: str) -> str:
        """One sentence for joint ``name``'s warning ``code``, with the measured numbers and the next step."""
        return explain_warning(self[name], code, self.threshold_rad, self.span_tolerance_rad)

    def to_report(self) -> dict[str, Any]:
        """The report: ``{"joints": {name: {sampled_min, sampled_max, sweep, homing_offset, ...}}}``."""
        return {"joints": {j.name: j.to_report() for j in self.joints}}


def explain_warning(
    joint: JointSweep,
    code: str,
    threshold_rad: float = DEFAULT_THRESHOLD_RAD,
    span_tolerance_rad: float = DEFAULT_SPAN_TOLERANCE_RAD,
) -> str:
    """One short sentence for a warning code: what was measured (numbers in rad) and what to do next.

    Args:
        joint: The joint's sweep outcome.
        code: One of :data:`WARNING_CODES`.
        threshold_rad: The not-swept threshold that was used, rad.
        span_tolerance_rad: The span tolerance that was used, rad.

    Returns:
        The sentence, without the joint name or the code (callers print ``JOINT: code: sentence``).
    """
    j = joint
    if code == "not_swept":
        if j.kept_prior and j.previous_homing_offset is not None:
            kept = f"the prior offset {j.previous_homing_offset:+.4f} rad was kept"
        else:
            kept = "there is no offset for it"
        todo = (
            f"push it into its {j.stop} stop and sweep again"
            if j.method == "one-sided"
            else "move it into both stops and sweep again"
        )
        return f"swept only {j.sweep:.3f} rad (threshold {threshold_rad:g} rad), so {kept}; {todo}"
    if code == "no_overlap":
        return (
            f"sampled range [{j.sampled_min:+.3f}, {j.sampled_max:+.3f}] rad does not overlap the URDF limits "
            f"[{j.lower:+.3f}, {j.upper:+.3f}] rad; its URDF direction is probably flipped: "
            "check it with --direction-check"
        )
    if code == "span_mismatch" and j.method == "one-sided":
        q_lo, q_hi = j.sampled_min - j.position_offset, j.sampled_max - j.position_offset
        return (
            f"with its {j.stop} stop at {j.stop_angle:+.3f} rad it moved over [{q_lo:+.3f}, {q_hi:+.3f}] rad, "
            f"past the URDF limits [{j.lower:+.3f}, {j.upper:+.3f}] (tolerance {span_tolerance_rad:g} rad); "
            "check the profile's stop angle and the URDF limits"
        )
    if code == "span_mismatch":
        diff = j.sweep - j.span
        return (
            f"swept {j.sweep:.3f} rad but the URDF span is {j.span:.3f} rad ({diff:+.3f} rad, tolerance "
            f"{span_tolerance_rad:g} rad); push it fully into both stops and sweep again, or correct the "
            "URDF limits"
        )
    if code == "offset_large":
        return (
            f"homing_offset {j.homing_offset:+.3f} rad is beyond ±π; check the URDF limits and direction, "
            "then sweep again"
        )
    if code == "wrap_in_travel":
        h, d = j.homing_offset, j.direction
        a = h + min(d * j.lower, d * j.upper)
        b = h + max(d * j.lower, d * j.upper)
        w = math.pi if j.zero_sta == 1 else 0.0
        k = math.floor((a - w) / math.tau) + 1.0
        return (
            f"its raw travel [{a:+.3f}, {b:+.3f}] rad contains the power-on wrap point {w + k * math.tau:+.3f} rad, "
            "so after a power cycle it can read 2π off; nothing to redo: the runtime robot and "
            "`robocal check --source` pick the turn inside the limits"
        )
    if code == "direction_flipped":
        return (
            "moved toward − when asked to move toward its + limit during the direction check; "
            f"flip its URDF direction (now {j.direction:+d}) and sweep again"
        )
    if code == "direction_unknown":
        return (
            "did not move 0.1 rad within the direction check's time, so its direction was NOT verified; "
            "rerun with --direction-check (and a longer --direction-time) and move it toward its + limit"
        )
    if code == "wrong_side":
        return (
            f"it was to be pushed into its {j.stop} stop ({j.stop_angle:+.3f} rad) but its reading only moved "
            f"the other way (sampled [{j.sampled_min:+.3f}, {j.sampled_max:+.3f}] rad): its direction "
            f"({j.direction:+d}) is probably flipped, or it went into the other stop; a joint that started at "
            "its stop shows this too. Check and sweep again"
        )
    return code
