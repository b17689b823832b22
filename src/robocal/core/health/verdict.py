"""The verdict a joint's range ends give (:mod:`.offsets`): pinned, together, clipped, or held by a position limit."""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from .offsets import HealthConfig, JointData

__all__ = ["EndEvidence", "judge_ends"]


@dataclass(frozen=True)
class EndEvidence:
    """What one range end shows.

    Attributes:
        end: ``lo`` or ``hi``.
        kind: ``pinned``, ``together`` or ``clipped``.
        follower: The follower's value at the end (``F``).
        leader: The leader's furthest value while the follower was there (``A``).
        lower: Lower bound on the offset from this end (``-inf``: none).
        upper: Upper bound (``inf``: none).
        frames: Frames at the end.
        episodes: Episodes those frames belong to.
        threshold: Smallest ``|F − A|`` a pinned end flags (``max(threshold_deg, band + ½°)``, this end's band).
        excess: How far the leader went on past the follower, beyond the sag holding the follower off the stop
            (pinned above this end's band).
    """

    end: str
    kind: str
    follower: float
    leader: float
    lower: float
    upper: float
    frames: int
    episodes: tuple[int, ...]
    threshold: float = 0.0
    excess: float = math.nan


def judge_ends(
    d: JointData, ends: list[EndEvidence], thr: float, cfg: HealthConfig
) -> tuple[str, float | None, tuple[float, float] | None, list[str], list[EndEvidence]]:
    """The verdict from a joint's (or an episode's) range ends; for a goal-limited follower, read as limits.

    A goal-limited follower (:attr:`JointData.goal_limited`) held short of its leader by less than the hand's scatter
    plus the threshold is what a correct calibration also shows: that end counts as ``together``, its bound widened
    by the hold. A longer hold is a calibration fault of that size on one of the arms whose sign the end cannot
    give (a follower-side offset holds both ends alike): ``suspect`` with the size, no offset and no interval.

    Returns:
        ``(status, offset, interval, reasons, ends)``, the ends as read.
    """
    if not d.goal_limited:
        return (*_verdict(ends, thr, cfg.ok_limit_deg * d.units_per_deg), ends)
    scatter = cfg.limit_scatter_deg * d.units_per_deg
    read: list[EndEvidence] = []
    held: list[EndEvidence] = []
    for e in ends:
        if e.kind == "pinned" and e.excess < scatter + e.threshold:
            bound = e.excess + 0.5 * d.units_per_deg + scatter
            lo, hi = (-bound, math.inf) if e.end == "hi" else (-math.inf, bound)
            e = replace(e, kind="together", lower=lo, upper=hi)
        elif e.kind == "pinned":
            held.append(e)
        read.append(e)
    status, est, ci, reasons = _verdict(read, thr, cfg.ok_limit_deg * d.units_per_deg)
    if not held:
        return status, est, ci, reasons, read
    says = [
        f"the follower stood {e.excess:.2f} short of its leader at the {'upper' if e.end == 'hi' else 'lower'} end "
        f"({e.follower:.2f} against {e.leader:.2f}), held by its position limit"
        for e in held
    ]
    if len(held) == 2:
        lead = 0.5 * (held[0].excess - held[1].excess) * (1.0 if held[0].end == "hi" else -1.0)
        says.append(
            f"both ends held: the follower's recorded range is about {sum(e.excess for e in held):.2f} shorter than "
            f"its leader's reach (a follower-side offset of up to ±{0.5 * sum(e.excess for e in held):.2f}, its "
            f"sign not in the data); if the leader was taken to its stop at both ends, their difference puts the "
            f"leader's own offset at {lead:+.2f} (a leader turned back short of a stop moves that figure)"
        )
    else:
        says.append(
            f"a calibration offset of up to {held[0].excess:.2f} on the leader or the follower; the range ends cannot "
            "give its sign (a follower-side offset holds both ends alike): --verify tells which arm"
        )
    return "suspect", None, None, says, read


def _verdict(
    ends: list[EndEvidence], thr: float, ok_limit: float
) -> tuple[str, float | None, tuple[float, float] | None, list[str]]:
    usable = [e for e in ends if e.kind != "clipped"]
    reasons: list[str] = []
    if not usable:
        return "unobservable", None, None, ["no range-end contact"]
    lo = max(e.lower for e in usable)
    hi = min(e.upper for e in usable)
    pinned = [e for e in usable if e.kind == "pinned"]
    est = None
    pin_thr = thr
    if pinned:
        best = max(pinned, key=lambda e: abs(e.follower - e.leader))
        est = best.follower - best.leader
        pin_thr = best.threshold
    if lo > hi + 1e-9:
        reasons.append(f"range ends disagree (bounds {lo:.2f} > {hi:.2f})")
        return "suspect", est, None, reasons
    if est is not None and abs(est) >= pin_thr:
        return "offset", est, (lo, hi), reasons
    if lo >= thr or hi <= -thr:
        est = lo if lo >= thr else hi
        return "offset", est, (lo, hi), reasons
    if math.isfinite(lo) and math.isfinite(hi) and -ok_limit <= lo and hi <= ok_limit:
        return "ok", est if est is not None else 0.5 * (lo + hi), (lo, hi), reasons
    if math.isfinite(lo) and math.isfinite(hi):
        reasons.append("neither range end pressed the follower against its stop")
    else:
        reasons.append(f"no range-end contact that would show a {'negative' if math.isinf(lo) else 'positive'} offset")
    for e in usable:
        if e.kind == "together":  # what a visited end shows: the follower came there with its leader, not held
            above = e.end == "hi"
            reasons.append(
                f"the {'upper' if above else 'lower'} end: the follower came to {e.follower:.2f} with its leader at "
                f"{e.leader:.2f}, not held by its stop (a {'negative' if above else 'positive'} offset shows there "
                "only as a follower held at its stop while the leader goes on)"
            )
    return "unobservable", est, None, reasons
