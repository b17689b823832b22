"""Per-joint calibration health from a teleoperation recording: range-end contacts, steps, mirrored signs, clipping.

Notation (one joint, the dataset's units; ``upd`` units per degree): ``a`` the leader's number (``action``), ``s``
the follower's (``observation.state``), ``sag`` the model's rest residual (:mod:`.model`). A calibration offset
``o = e_follower − e_leader`` (what the follower reads minus what the leader reads at the same physical angle)
moves the arms ``o`` apart while ``a`` and ``s`` agree. It shows only at a range end:

* **pinned** — at the upper end with ``o < 0`` the follower meets its stop first (reading ``F = stop + e_F``) while
  the leader goes on to its own (``A = stop + e_L``): ``o = F − A``, measured (both arms held at the end give the
  value, a leader that stopped short a lower bound on ``|o|``). The lower end mirrors it (``o > 0``).
* **together** — the arms reach the end with the same number: the offset has not the sign that end would show,
  a one-sided bound (upper end: ``o ≥ −(band + gap)``; lower end: ``o ≤ band + gap``; ``gap`` how far the follower
  stayed from the end's expected reading).
* **clipped** — the follower's value sits bit-for-bit constant at its extreme while the leader goes on: a value
  clamped at a calibrated range end (a real encoder pressed on a stop jitters by a tick); not an offset reading.

Verdicts: ``offset`` (a pinned end or the bounds put ``|o|`` past the threshold), ``ok`` (both ends bound ``o``
inside ``±ok_limit``), ``suspect`` (a step in the follower's reading no commanded motion explains, a mirrored
sign, clipping, ends that contradict each other, episodes that disagree), ``unobservable`` (otherwise: the data
cannot show an offset of at least one sign).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from ..arrays import FloatArray, IntArray
from .ends import end_bands, end_raw_caps
from .level import RestLevel, rest_level
from .model import fitted_sag, model_band
from .sag import last_direction
from .verdict import EndEvidence, judge_ends

__all__ = [
    "EndEvidence",
    "HealthConfig",
    "JointData",
    "JointHealth",
    "JumpEvent",
    "analyse_joint",
    "drift_reason",
    "episode_verdicts",
    "fitted_joint",
]


@dataclass(frozen=True)
class HealthConfig:
    """Thresholds, in degrees (scaled by a joint's units per degree).

    Attributes:
        threshold_deg: Smallest offset flagged ``offset``.
        ok_limit_deg: ``ok`` needs the interval inside ``±ok_limit_deg``.
        window_deg: A follower extreme farther than this inside the end's expected reading is not a range end.
        near_deg: Readings within this of the follower's extreme count as "at the end" (stop compliance, ticks).
        slow_deg: Slow frames move less than this per frame (the band is fitted on them).
        band_floor_deg: Smallest model band (dead band and ticks).
        jump_floor_deg: Smallest step reported as a jump.
        min_frames: Frames at an end needed for evidence.
        clip_frames: Bit-identical frames at an extreme (and 90 % of the frames there) that make a clipped value.
        end_margin_deg: Added to a range end's own band (:func:`end_bands`): the end's excess is the extreme of
            many frames, the band a spread of single frames.
        limit_scatter_deg: How far inside its stops the hand may have recorded a range end: a follower whose servo
            enforces its position limits (``JointData.goal_limited``) is held that far short of its leader at an end
            by a correct calibration.
        level_deg: How far from its goal a correct follower may rest at every pose (:mod:`.level`), beyond its
            modelled sag; the band is used where it is wider.
        sag_level_deg: The rest level a loaded joint may have for the sag-pattern fit to be used (a constant in its
            residual would be read as offsets of other joints).
        sag_confidence: The sag fit's interval that must lie beyond ``±threshold_deg`` for an ``offset`` from the
            sag pattern alone (0.999: three loaded joints at 99 % flagged 2 of 200 offset-free SO-101 sessions).
    """

    threshold_deg: float = 1.5
    ok_limit_deg: float = 3.0
    window_deg: float = 30.0
    near_deg: float = 0.6
    slow_deg: float = 0.3
    band_floor_deg: float = 0.5
    jump_floor_deg: float = 3.0
    min_frames: int = 3
    clip_frames: int = 10
    end_margin_deg: float = 0.25
    limit_scatter_deg: float = 1.5
    level_deg: float = 3.0
    sag_level_deg: float = 0.5
    sag_confidence: float = 0.999


@dataclass(frozen=True, eq=False)
class JointData:
    """One joint's frames.

    Attributes:
        name: Joint name.
        action: ``(N,)`` leader values.
        state: ``(N,)`` follower values.
        episode: ``(N,)`` episode index of each frame (frames of an episode consecutive, in order).
        sag: ``(N,)`` modelled rest residual (``action − state``), same units.
        stop_lo: Expected reading of the lower stop for a correct calibration (NaN: none known).
        stop_hi: Same, upper stop.
        units_per_deg: Dataset units per degree (1 in degrees).
        sag_fitted: ``sag`` was fitted from these frames (no URDF masses): it is extrapolated at the range ends, so a
            pinned end must also stand out of the raw residual (:func:`end_raw_caps`).
        goal_limited: The follower's servo clamps its goal to its position limits, where LeRobot wrote the recorded
            range (an SO-101's STS3215s): at a range end it stands at its limit, not pressed into its stop. Its
            limits read ``[lo + x + |e_F|, hi − x − |e_F|]`` in its own frame (``x`` the hand's scatter, ``e_F`` its
            offset), so a held end shows ``x + |e_F| ± e_L``: how far the calibrations disagree, not the sign.
        sag_limit: The largest sag the follower's servo can hold, ``τ_stall / kp`` in the values' units (``inf``:
            not known): bounds what a fitted sag may explain of the rest level (:mod:`.level`).
    """

    name: str
    action: FloatArray
    state: FloatArray
    episode: IntArray
    sag: FloatArray
    stop_lo: float = math.nan
    stop_hi: float = math.nan
    units_per_deg: float = 1.0
    sag_fitted: bool = False
    goal_limited: bool = False
    sag_limit: float = math.inf


@dataclass(frozen=True)
class JumpEvent:
    """A step in the follower's reading that the commanded motion cannot explain.

    Attributes:
        episode: Episode index.
        frame: Frame index within the episode.
        size: Step size (dataset units).
    """

    episode: int
    frame: int
    size: float


@dataclass(frozen=True, eq=False)
class JointHealth:
    """The verdict on one joint (dataset units).

    Attributes:
        name: Joint name.
        status: ``ok``, ``unobservable``, ``suspect`` or ``offset``.
        offset: Offset estimate (follower minus leader calibration) or None.
        ci: ``(lo, hi)`` interval or None.
        reasons: Sentences behind the verdict.
        ends: Evidence per range end.
        jumps: Steps located in time.
        band: Model band half-width.
        residual: ``(N,)`` ``action(t−1) − state(t) − sag(t)`` (NaN at an episode's first frame).
        used: ``(N,)`` frames the band was fitted on or an end was read from.
        end_bands: ``(lower end, upper end)``: how far a correct follower's residual goes towards each end when it
            comes from the middle (:func:`end_bands`).
        raw_caps: ``(lower end, upper end)``: the largest raw residual towards each end elsewhere when the sag was
            fitted from the data (:func:`end_raw_caps`; ``-inf``: not used).
    """

    name: str
    status: str
    offset: float | None
    ci: tuple[float, float] | None
    reasons: tuple[str, ...]
    ends: tuple[EndEvidence, ...]
    jumps: tuple[JumpEvent, ...]
    band: float
    residual: FloatArray = field(repr=False)
    used: FloatArray = field(repr=False)
    end_bands: tuple[float, float] = (math.nan, math.nan)
    raw_caps: tuple[float, float] = (-math.inf, -math.inf)
    rest: RestLevel | None = None


def fitted_joint(
    name: str,
    action: FloatArray,
    state: FloatArray,
    episode: IntArray,
    pose_deg: FloatArray,
    stop_lo: float,
    stop_hi: float,
    units_per_deg: float = 1.0,
    cfg: HealthConfig | None = None,
    goal_limited: bool = False,
) -> JointData:
    """A joint with stops but no URDF masses, its sag fitted from its own frames (the dataset check's Koch path).

    The sag is :func:`~.model.fitted_sag` with the friction dead band's side (the sign of the reading's last move)
    as a fourth column, and ``sag_fitted`` set: a pinned end must also stand out of the raw residual
    (:func:`~.ends.end_raw_caps`).
    """
    c = cfg or HealthConfig()
    u = units_per_deg
    way = last_direction(state, episode, 0.5 * c.near_deg * u)
    sag = fitted_sag(action, state, episode, pose_deg, c.slow_deg * u, 3.0 * u, way)
    return JointData(name, action, state, episode, sag, stop_lo, stop_hi, u, sag_fitted=True, goal_limited=goal_limited)


def _lagged(d: JointData) -> tuple[FloatArray, FloatArray, FloatArray]:
    """(same-episode mask of t vs t−1, a(t−1), |Δa(t)|) with NaN where t is an episode's first frame."""
    same = np.zeros(d.action.shape, dtype=bool)
    same[1:] = d.episode[1:] == d.episode[:-1]
    a_prev = np.full(d.action.shape, np.nan)
    a_prev[1:] = d.action[:-1]
    a_prev[~same] = np.nan
    da = np.full(d.action.shape, np.nan)
    da[1:] = np.abs(np.diff(d.action))
    da[~same] = np.nan
    return same.astype(np.float64), a_prev, da


def _jumps(d: JointData, same: FloatArray, cfg: HealthConfig) -> tuple[JumpEvent, ...]:
    """Steps in ``s`` that the follower's own tracking dynamics cannot explain.

    The follower's motion is fitted per joint as a second-order linear response to the commands,
    ``Δs(t) = c1·(a(t−1) − s(t−1)) + c2·(a(t−2) − s(t−2)) + c3·Δs(t−1)`` (least squares, refitted without the
    outliers); a frame whose prediction error passes ``max(jump_floor, 8·σ)`` (σ from the median absolute
    error) and 40 % of the commanded speed, and moves the reading away from the goal is a step (friction lets a follower stick, then jump
    *towards* its goal). Frames at the follower's extremes (a stop holds it, the linear response does not apply)
    are left out of the fit, and judged only when the reading itself jumped away from its goal by more than the
    threshold. Frames within three of the follower running at its top speed (velocity-limited, not linear) are
    not judged.
    """
    s, a = d.state, d.action
    n = s.size
    hist = np.zeros(n, dtype=bool)
    hist[3:] = (same[3:] > 0) & (same[2:-1] > 0) & (same[1:-2] > 0)
    lo_x, hi_x = float(np.min(s)), float(np.max(s))
    edge = cfg.near_deg * 3 * d.units_per_deg
    ok = hist.copy()
    for lag in (0, 1):
        sl = np.roll(s, lag)
        ok &= (sl > lo_x + edge) & (sl < hi_x - edge)
    idx = np.flatnonzero(ok)
    if idx.size < 20:
        return ()
    y = s[idx] - s[idx - 1]
    x = np.stack([a[idx - 1] - s[idx - 1], a[idx - 2] - s[idx - 2], s[idx - 1] - s[idx - 2]], axis=1)
    keep = np.ones(idx.size, dtype=bool)
    err = y
    for _ in range(2):
        coef, *_ = np.linalg.lstsq(x[keep], y[keep], rcond=None)
        err = y - x @ coef
        sigma = 1.4826 * float(np.median(np.abs(err - np.median(err)))) + 1e-9
        keep = np.abs(err) < 6 * sigma
    thr = max(cfg.jump_floor_deg * d.units_per_deg, 8.0 * sigma)
    # a frame at the extremes is judged too when its reading itself jumped away from the goal by more than the
    # threshold: a stop holds a follower still, it never throws it away from its goal (a slip's own reading is
    # often the session's extreme)
    ds = np.zeros(n)
    ds[1:] = np.diff(s)
    away = np.zeros(n)  # how much further from its goal the reading moved in the frame
    away[1:] = np.abs(a[:-1] - s[1:]) - np.abs(a[:-1] - s[:-1])
    thrown = hist & ~ok & (np.abs(ds) > thr) & (away > 0.5 * thr)
    idx = np.union1d(idx, np.flatnonzero(thrown))
    x = np.stack([a[idx - 1] - s[idx - 1], a[idx - 2] - s[idx - 2], s[idx - 1] - s[idx - 2]], axis=1)
    err = s[idx] - s[idx - 1] - x @ coef
    events: list[JumpEvent] = []
    last = -10
    # a slipped reading jumps away from the goal; a follower breaking free of friction jumps towards it
    grows = np.abs(a[idx - 1] - s[idx]) > np.abs(a[idx - 2] - s[idx - 1]) + 0.5 * thr
    # the linear response fits fast moves less well: a step must also pass 40 % of the commanded speed
    speed = np.maximum(np.abs(a[idx - 1] - a[idx - 2]), np.abs(a[idx - 2] - a[idx - 3]))
    # right after the follower ran at its top speed (a flick of the leader it could not keep up with) its servo
    # is not in the linear regime the fit describes: its reversal out of that run is no step
    v = np.abs(ds)
    v_top = float(np.percentile(v[ok], 99.5))
    fast = np.zeros(idx.size, dtype=bool)
    if v_top > 2.0 * thr:
        for lag in (1, 2, 3):
            fast |= v[np.clip(idx - lag, 0, None)] >= 0.7 * v_top
    for k in np.flatnonzero((np.abs(err) > np.maximum(thr, 0.4 * speed)) & grows & ~fast):
        t = int(idx[k])
        if t - last > 3:
            ep = int(d.episode[t])
            first = int(np.flatnonzero(d.episode == ep)[0])
            events.append(JumpEvent(ep, t - first, float(err[k])))
        last = t
    return tuple(events)


def _end(
    d: JointData, sgn: float, band: float, cfg: HealthConfig, mask: np.ndarray, raw_cap: float = -math.inf
) -> EndEvidence | None:
    """Evidence at the upper (``sgn`` +1) or lower (−1) end from the frames in ``mask``."""
    stop = d.stop_hi if sgn > 0 else d.stop_lo
    if not math.isfinite(stop) or not mask.any():
        return None
    upd = d.units_per_deg
    fv, av = sgn * d.state[mask], sgn * d.action[mask]
    f_ext = float(np.max(fv))
    if f_ext < sgn * stop - cfg.window_deg * upd:
        return None
    near = fv >= f_ext - cfg.near_deg * upd
    if int(near.sum()) < cfg.min_frames:
        return None
    idx = np.flatnonzero(near)
    prev = np.clip(idx - 1, 0, None)
    a_ext = float(max(np.max(av[idx]), np.max(av[prev])))
    sag_away = max(0.0, float(np.median(sgn * d.sag[mask][near])))  # gravity holding it off the stop
    excess = a_ext - f_ext - sag_away
    eps = tuple(sorted({int(e) for e in d.episode[mask][near]}))
    u = 0.5 * upd + 0.5 * band
    name = "hi" if sgn > 0 else "lo"
    thr = max(cfg.threshold_deg * upd, band + 0.5 * upd)
    if excess > band and a_ext - f_ext > raw_cap:
        same = int(np.sum(fv == f_ext))
        if same >= cfg.clip_frames and same >= 0.9 * len(idx):
            return EndEvidence(name, "clipped", sgn * f_ext, sgn * a_ext, -math.inf, math.inf, len(idx), eps, thr, excess)
        held = int(np.sum(av[idx] >= a_ext - 0.25 * upd)) >= 5
        o = -sgn * excess
        # the leader may have stopped short of its stop: unless it rested right at the stop's expected reading,
        # widen towards a larger offset by what it had left plus a third of the window (an operator stopping
        # short, or a leader whose own offset moves its reading)
        at_stop = held and abs(a_ext - sgn * stop) <= 1.5 * upd
        slack = 0.0 if at_stop else max(0.0, sgn * stop - a_ext) + cfg.window_deg / 3 * upd
        # a follower pressed well into its stop does not sag (the stop holds it): the offset is then F − A itself,
        # so the interval reaches from the sag-corrected value to the uncorrected one
        slack += sag_away
        lo, hi = (o - u - slack, o + u) if sgn > 0 else (o - u, o + u + slack)
        return EndEvidence(name, "pinned", sgn * f_ext, sgn * a_ext, lo, hi, len(idx), eps, thr, excess)
    gap = max(0.0, sgn * stop - f_ext)
    bound = band + u + gap
    lo, hi = (-bound, math.inf) if sgn > 0 else (-math.inf, bound)
    return EndEvidence(name, "together", sgn * f_ext, sgn * a_ext, lo, hi, len(idx), eps, thr, excess)


def _rest_verdict(
    d: JointData,
    rest: RestLevel | None,
    band: float,
    cfg: HealthConfig,
    verdict: tuple[str, float | None, tuple[float, float] | None],
    reasons: list[str],
) -> tuple[str, float | None, tuple[float, float] | None]:
    """The verdict with the follower's rest level (:mod:`.level`): past what sag and dead band allow, an offset.

    A modelled sag leaves ``max(level_deg, band)``; a fitted one (no URDF masses: its share of the level is not
    known) also the largest sag the servo can hold (``sag_limit``), which widens the interval by as much. The
    offset is ``−typical`` (follower minus leader); an offset the range ends already measured is kept.
    """
    status, est, ci = verdict
    upd = d.units_per_deg
    sag_share = d.sag_limit if d.sag_fitted else 0.0
    allow = max(cfg.level_deg * upd, band) + sag_share
    if rest is None or not abs(rest.level) > allow:
        return status, est, ci
    lo_pose, hi_pose = rest.bins[0][0], rest.bins[-1][0]
    reasons.append(
        f"at rest the leader's number exceeds the follower's by {rest.typical:+.2f} (at least {rest.level:+.2f} at every "
        f"pose: {len(rest.bins)} poses from {lo_pose:.1f} to {hi_pose:.1f}, {rest.frames} slow frames), where a correct "
        f"follower rests within {allow:.2f} of its goal (its sag and dead band): action and observation.state are not "
        "in one calibration frame (a calibration that changed between them, or a column edited after the recording)"
    )
    if status == "offset":
        return status, est, ci
    off = -rest.typical
    u = 0.5 * band + 0.5 * upd + sag_share
    return "offset", off, (off - u, off + u)


def analyse_joint(d: JointData, cfg: HealthConfig | None = None) -> JointHealth:
    """Calibration health of one joint (see the module docstring).

    Args:
        d: The joint's frames and expected stop readings.
        cfg: Thresholds (default :class:`HealthConfig`).

    Returns:
        The verdict, its evidence and the residual trace.
    """
    cfg = cfg or HealthConfig()
    upd = d.units_per_deg
    same, a_prev, da = _lagged(d)
    residual = a_prev - d.state - d.sag
    slow = (np.nan_to_num(da, nan=np.inf) < cfg.slow_deg * upd) & (
        np.nan_to_num(np.roll(da, 1), nan=np.inf) < cfg.slow_deg * upd
    )
    band = model_band(residual[slow & np.isfinite(residual)], cfg.band_floor_deg * upd)
    used = slow.astype(np.float64)
    thr = max(cfg.threshold_deg * upd, band + 0.5 * upd)
    moving = float(np.ptp(d.action)) if d.action.size else 0.0
    if moving < 1.0 * upd:
        return JointHealth(
            d.name, "unobservable", None, None, ("the joint does not move",), (), (), band, residual, used
        )
    if np.std(d.state) > 0 and np.std(d.action) > 0:
        r = float(np.corrcoef(d.action, d.state)[0, 1])
        if r < -0.5:
            return JointHealth(
                d.name,
                "suspect",
                None,
                None,
                (f"sign flip: action mirrors observation.state (correlation {r:.2f})",),
                (),
                (),
                band,
                residual,
                used,
            )
    rest = rest_level(a_prev, d.state, np.zeros_like(d.sag) if d.sag_fitted else d.sag, slow, 3 * upd, 10 * upd)
    jumps = _jumps(d, same, cfg)
    everything = np.ones(d.action.shape, dtype=bool)
    b_lo, b_hi = end_bands(d, residual, slow, band, cfg)
    c_lo, c_hi = end_raw_caps(d, slow, cfg)
    ends = [
        e for e in (_end(d, 1.0, b_hi, cfg, everything, c_hi), _end(d, -1.0, b_lo, cfg, everything, c_lo)) if e
    ]
    for e in ends:
        sgn = 1.0 if e.end == "hi" else -1.0
        used[sgn * d.state >= sgn * e.follower - cfg.near_deg * upd] = 2.0
    status, est, ci, reasons, ends = judge_ends(d, ends, thr, cfg)
    for e in ends:
        if e.kind == "pinned" and status == "offset":
            reasons.append(
                f"follower pinned at the {'upper' if e.end == 'hi' else 'lower'} end ({e.follower:.2f}) while "
                f"the leader went on to {e.leader:.2f}"
            )
        if e.kind == "clipped":
            reasons.append(
                f"values clipped at {e.follower:.2f} ({e.frames} identical frames) while the leader "
                f"went on to {e.leader:.2f}: a calibrated range end short of the stop"
            )
            if status != "offset":
                status = "suspect"
    status, est, ci = _rest_verdict(d, rest, band, cfg, (status, est, ci), reasons)
    if jumps:
        reasons.append(
            "; ".join(f"step of {j.size:+.2f} in episode {j.episode} frame {j.frame}" for j in jumps)
        )
        if status != "offset":
            status = "suspect"
    return JointHealth(
        d.name, status, est, ci, tuple(reasons), tuple(ends), jumps, band, residual, used, (b_lo, b_hi), (c_lo, c_hi),
        rest,
    )


def episode_verdicts(
    d: JointData,
    band: float,
    cfg: HealthConfig | None = None,
    end_band: tuple[float, float] | None = None,
    raw_caps: tuple[float, float] = (-math.inf, -math.inf),
) -> list[dict[str, object]]:
    """Per-episode offset, interval and verdict from that episode's range-end evidence alone.

    ``end_band``: the session's :func:`end_bands` (``(lower, upper)``; default the symmetric ``band`` at both);
    ``raw_caps``: the session's :func:`end_raw_caps`.
    """
    cfg = cfg or HealthConfig()
    thr = max(cfg.threshold_deg * d.units_per_deg, band + 0.5 * d.units_per_deg)
    b_lo, b_hi = end_band if end_band is not None else (band, band)
    out: list[dict[str, object]] = []
    for ep in np.unique(d.episode):
        mask = d.episode == ep
        ends = [e for e in (_end(d, 1.0, b_hi, cfg, mask, raw_caps[1]), _end(d, -1.0, b_lo, cfg, mask, raw_caps[0])) if e]
        status, est, ci, _, _ = judge_ends(d, ends, thr, cfg)
        out.append({"episode": int(ep), "offset": est, "ci": ci, "status": status, "frames": int(mask.sum())})
    return out


def drift_reason(episodes: list[dict[str, object]], band: float, cfg: HealthConfig, units_per_deg: float) -> str | None:
    """A sentence when the episodes' own measured offsets disagree by more than twice the threshold, else None.

    Only episodes that measured an offset at a range end (``offset`` or ``ok`` with a number) take part: a
    calibration that moved during the session (a slip, a drift) shows as two episodes with different offsets.
    """
    thr = max(cfg.threshold_deg * units_per_deg, band + 0.5 * units_per_deg)
    measured = [
        (int(e["episode"]), float(e["offset"]))  # type: ignore[call-overload, arg-type]
        for e in episodes
        if e["status"] in ("offset", "ok") and e["offset"] is not None
    ]
    if len(measured) < 2:
        return None
    lo = min(measured, key=lambda m: m[1])
    hi = max(measured, key=lambda m: m[1])
    if hi[1] - lo[1] <= 2 * thr:
        return None
    return (
        f"the offset changes between episodes: {lo[1]:+.2f} in episode {lo[0]}, {hi[1]:+.2f} in episode {hi[0]}"
    )
