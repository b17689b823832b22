"""Calibration health of a LeRobot v3 teleoperation dataset: read the frames, run the per-joint check, report.

``action`` is the leader's reading, ``observation.state`` the follower's, both in the arm's normalised units
(degrees for SO arms since LeRobot v0.4.4, ``range_m100_100`` otherwise, the gripper ``range_0_100``). With the
leader's and the follower's calibration files both values become degrees about each arm's calibrated middle
(``(actual − middle)·360/4096``) and the follower file's recorded range gives the stops; without them the values
stay in the dataset's units and the stops are the robot profile's (degrees mode) or the range ends (±100, 0..100).
The check itself is :func:`robocal.core.health.analyse_joint`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np

from ..core.arrays import FloatArray, IntArray
from ..core.gravity import GravityModel
from ..core.health import (
    HealthConfig,
    JointData,
    JointHealth,
    SagFit,
    analyse_joint,
    drift_reason,
    episode_verdicts,
    fit_sag_offsets,
    fitted_joint,
    loaded_joints,
    sag_residual_deg,
    sag_slopes,
)
from ..errors import UsageError
from ._convention import ValueConvention
from .teleop_frames import TeleopFrames, read_teleop_frames

__all__ = [
    "DatasetHealth",
    "HealthSetup",
    "TeleopFrames",
    "dataset_health",
    "health_json",
    "read_teleop_frames",
]

TICKS_PER_TURN = 4096
_FULL_TURN_DEG = 359.0
"""A recorded range this wide is LeRobot's full-turn motor (``0..4095``), not a range between stops."""


@dataclass(frozen=True)
class HealthSetup:
    """What the check expects of each joint (built from the robot profile, URDF and calibration files).

    Attributes:
        units: Joint → the dataset's units (``degrees``, ``range_m100_100``, ``range_0_100``).
        units_per_deg: Joint → units per degree (NaN: unknown).
        stop_deg: Joint → ``(lower, upper)`` stop angles of a correct calibration in degrees, or None.
        kp_nm_rad: Joint → the follower's position gain.
        gravity: The arm's gravity model (URDF masses), or None (no sag model).
        leader: The leader's calibration (``action``), or None.
        follower: The follower's calibration (``observation.state``), or None.
        goal_limited: Joint → the follower's servo clamps its goal to its position limits (LeRobot's recorded
            range: Feetech STS in position mode; :attr:`robocal.core.health.JointData.goal_limited`).
        sag_limit_deg: Joint → the largest sag its servo can hold, ``τ_stall / kp`` in degrees (missing: not known).
    """

    units: dict[str, str]
    units_per_deg: dict[str, float]
    stop_deg: dict[str, tuple[float, float] | None]
    kp_nm_rad: dict[str, float]
    gravity: GravityModel | None = None
    leader: ValueConvention | None = None
    follower: ValueConvention | None = None
    goal_limited: dict[str, bool] = field(default_factory=dict)
    sag_limit_deg: dict[str, float] = field(default_factory=dict)


@dataclass(frozen=True, eq=False)
class DatasetHealth:
    """Result of :func:`dataset_health`.

    Attributes:
        root: Dataset root.
        frames: Frames read.
        episodes: Episodes read.
        joints: Per joint: verdict, units, per-episode verdicts, notes.
        pose: ``(N, J)`` the follower's pose in the check's units (the picture's x axis).
        sag: The sag-pattern fit of the loaded joints (None: no gravity model, or too little data).
    """

    root: Path
    frames: int
    episodes: int
    joints: tuple[tuple[JointHealth, str, float, list[dict[str, Any]], list[str]], ...]
    pose: FloatArray
    sag: SagFit | None = None

    @property
    def flagged(self) -> tuple[str, ...]:
        """Joints whose verdict is ``offset`` or ``suspect``."""
        return tuple(h.name for h, *_ in self.joints if h.status in ("offset", "suspect"))


def _to_degrees(
    conv: ValueConvention, joints: tuple[str, ...], values: FloatArray
) -> tuple[FloatArray, FloatArray]:
    """Values → degrees about the calibration's middle; also the calibrated range ends in those degrees ``(2, J)``."""
    sel = conv.select(list(joints))
    rng = sel.value_range()
    if rng is None:
        lo_v, hi_v = np.full(len(joints), np.nan), np.full(len(joints), np.nan)
        mid_v = np.zeros(len(joints))
    else:
        lo_v, hi_v = np.asarray(rng[0], dtype=np.float64), np.asarray(rng[1], dtype=np.float64)
        mid_v = 0.5 * (lo_v + hi_v)
    mid_t = sel.to_actual(mid_v[None, :])[0]
    scale = 360.0 / TICKS_PER_TURN
    deg = (sel.to_actual(values) - mid_t) * scale
    ends = np.stack([sel.to_actual(lo_v[None, :])[0], sel.to_actual(hi_v[None, :])[0]]) - mid_t
    return deg, np.sort(ends * scale, axis=0)


_UNIT_BOUNDS = {"degrees": (-360.0, 360.0), "range_m100_100": (-100.0, 100.0), "range_0_100": (0.0, 100.0)}
"""What a LeRobot arm can record in each unit: degrees about the recorded middle stay within one turn of it; the
range modes are clamped to their ends."""


def _impossible(unit: str, action: FloatArray, state: FloatArray, episode: IntArray) -> str | None:
    """A reason when one of the arms records a value its units cannot hold (a corrupted value, another unit)."""
    if unit not in _UNIT_BOUNDS:
        return None
    lo, hi = _UNIT_BOUNDS[unit]
    tol = 1e-3 * (hi - lo)
    for feature, arm, v in (("action", "leader", action), ("observation.state", "follower", state)):
        bad = np.flatnonzero((v < lo - tol) | (v > hi + tol))
        if bad.size:
            i = int(bad[0])
            return (
                f"{feature} (the {arm}) reads {v[i]:.6g} in frame {i} (episode {int(episode[i])}), {bad.size} "
                f"frame(s) outside {lo:g}..{hi:g}, all a LeRobot arm records in {unit}: not a reading of this "
                "joint (a corrupted value or another unit); no offset is estimated"
            )
    return None


def _stop_readings(stop_deg: tuple[float, float] | None, units: str, upd: float) -> tuple[float, float]:
    """The readings a correct calibration gives at the stops, in the check's units (NaN: no stops)."""
    if stop_deg is None:
        return math.nan, math.nan
    if units == "range_0_100":
        return 0.0, 100.0
    if units == "range_m100_100":
        return -100.0, 100.0
    return stop_deg[0] * upd, stop_deg[1] * upd


def dataset_health(root: str | Path, setup: HealthSetup, cfg: HealthConfig | None = None) -> DatasetHealth:
    """Check every joint of a teleoperation dataset (see the module docstring).

    Raises:
        FileFormatError, JointMismatchError, UsageError: A dataset the check cannot read (see
            :func:`read_teleop_frames`), or no joint moves.
    """
    fr = read_teleop_frames(root)
    joints = fr.joints
    if float(np.max(np.ptp(fr.action, axis=0))) == 0.0 and float(np.max(np.ptp(fr.state, axis=0))) == 0.0:
        raise UsageError(f"dataset {fr.root}: no joint moves in any frame; nothing to check")
    action, state = fr.action, fr.state
    units = [setup.units.get(j, "units") for j in joints]
    upd = [setup.units_per_deg.get(j, math.nan) for j in joints]
    stops: list[tuple[float, float] | None] = [setup.stop_deg.get(j) for j in joints]
    notes: list[list[str]] = [[] for _ in joints]  # flag the joint (suspect)
    impossible = [_impossible(units[k], action[:, k], state[:, k], fr.episode) for k in range(len(joints))]
    info: list[list[str]] = [[] for _ in joints]  # said, not flagged
    if setup.leader is not None and setup.follower is not None:
        action, lead_ends = _to_degrees(setup.leader, joints, action)
        state, foll_ends = _to_degrees(setup.follower, joints, state)
        units, upd = ["degrees"] * len(joints), [1.0] * len(joints)
        for k in range(len(joints)):
            span_l, span_f = float(np.diff(lead_ends[:, k])[0]), float(np.diff(foll_ends[:, k])[0])
            design = stops[k]
            if design is not None and min(span_l, span_f) >= _FULL_TURN_DEG:
                # LeRobot's full-turn motor (wrist_roll: 0..4095): the range is not the stops; the profile's stay
                info[k].append(
                    "recorded as a full turn in the calibration files: its zero is the homing pose, which the files "
                    "do not carry; only the follower held at a stop can show its offset"
                )
            elif design is not None and math.isfinite(span_l) and math.isfinite(span_f):
                stops[k] = (float(foll_ends[0, k]), float(foll_ends[1, k]))
                if abs(span_l - span_f) > 5.0:
                    gap = abs(span_l - span_f)
                    notes[k].append(
                        f"recorded ranges differ: leader {span_l:.1f}°, follower {span_f:.1f}° (calibration files; "
                        f"the profile's stops span {design[1] - design[0]:.1f}°): a range recorded {gap:.1f}° short "
                        f"at one end moves that arm's zero by up to ±{gap / 2:.1f}°"
                    )
    pose_deg = np.array(state / np.where(np.isfinite(upd), upd, 1.0), dtype=np.float64)
    kp = [setup.kp_nm_rad.get(j, math.inf) for j in joints]
    sag_deg = sag_residual_deg(setup.gravity, joints, pose_deg, kp) if setup.gravity is not None else None
    fit = None
    if setup.gravity is not None and sag_deg is not None:
        lead_deg = np.array(action / np.where(np.isfinite(upd), upd, 1.0), dtype=np.float64)
        fit = _sag_fit(setup.gravity, joints, pose_deg, lead_deg, sag_deg, fr.episode, kp, stops)
    out = []
    analysed: list[tuple[JointData, JointHealth]] = []
    for k, j in enumerate(joints):
        u = upd[k] if math.isfinite(upd[k]) else 1.0
        lo, hi = _stop_readings(stops[k], units[k], u)
        limited = setup.goal_limited.get(j, False)
        if sag_deg is not None:
            data = JointData(j, action[:, k], state[:, k], fr.episode, sag_deg[:, k] * u, lo, hi, u, goal_limited=limited)
        elif stops[k] is not None:  # no URDF masses: the sag's shape fitted from the data (narrows the band)
            data = fitted_joint(j, action[:, k], state[:, k], fr.episode, pose_deg[:, k], lo, hi, u, cfg, limited)
            data = replace(data, sag_limit=setup.sag_limit_deg.get(j, math.inf) * u)
        else:
            data = JointData(j, action[:, k], state[:, k], fr.episode, np.zeros(len(action)), lo, hi, u, goal_limited=limited)
        analysed.append((data, analyse_joint(data, cfg)))
    unfit = _sag_fit_unusable(fit, analysed, joints, cfg or HealthConfig())
    for k, (data, h) in enumerate(analysed):
        u = data.units_per_deg
        if unfit is not None and fit is not None and h.status == "unobservable" and k in fit.joints:
            h = replace(h, reasons=(*h.reasons, unfit))
        h = _with_sag(h, fit if unfit is None else None, k, u, cfg or HealthConfig())
        episodes = episode_verdicts(data, h.band, cfg, h.end_bands, h.raw_caps)
        drift = drift_reason(episodes, h.band, cfg or HealthConfig(), u)
        extra = [*notes[k], *([drift] if drift else [])]
        bad = impossible[k]
        if bad is not None:  # the numbers above are not of this joint: no offset from them
            extra.insert(0, bad)
            h = replace(h, status="suspect", offset=None, ci=None, reasons=(bad, *h.reasons, *extra[1:]))
        elif extra:
            status = h.status if h.status == "offset" else "suspect"
            h = replace(h, status=status, reasons=(*h.reasons, *extra))
        if info[k]:
            h = replace(h, reasons=(*h.reasons, *info[k]))
        out.append((h, units[k], u if math.isfinite(upd[k]) else math.nan, episodes, extra))
    used = fit if unfit is None else None
    return DatasetHealth(fr.root, len(fr.episode), len(np.unique(fr.episode)), tuple(out), state, used)


def _sag_fit_unusable(
    fit: SagFit | None, analysed: list[tuple[JointData, JointHealth]], joints: tuple[str, ...], cfg: HealthConfig
) -> str | None:
    """Why the sag fit may not be used (a loaded joint's rest level breaks its premise), or None.

    The fit reads offsets from how ``a(t−1) − s(t) − sag`` varies with pose; a joint whose follower rests away from
    its goal at every pose (a shifted column, :mod:`robocal.core.health.level`) puts a constant into that residual,
    which the fit explains as offsets on other joints (a 2° shoulder_lift shift read as elbow_flex −100°).
    """
    for k in fit.joints if fit is not None else ():
        data, h = analysed[k]
        rest, u = h.rest, data.units_per_deg
        if rest is not None and abs(rest.level) > cfg.sag_level_deg * u:
            return (
                f"the sag pattern was not used: at rest {joints[k]}'s leader number exceeds its follower's by "
                f"{rest.level / u:+.2f}° at every pose (the sag fit needs that within ±{cfg.sag_level_deg:g}°)"
            )
    return None


def _sag_fit(
    gravity: GravityModel,
    joints: tuple[str, ...],
    pose_deg: FloatArray,
    lead_deg: FloatArray,
    sag_deg: FloatArray,
    episode: IntArray,
    kp: list[float],
    stops: list[tuple[float, float] | None],
) -> SagFit | None:
    """The follower's offsets from its sag pattern (:mod:`robocal.core.health.sag`), loaded joints with stops."""
    cand = [k for k, j in enumerate(joints) if stops[k] is not None and j in gravity.joint_names]
    if not cand:
        return None
    slope = sag_slopes(gravity, joints, pose_deg, kp, cand)
    rms = np.sqrt(np.mean(slope**2, axis=0)).sum(axis=0)  # per offset: its effect summed over the joints
    keep = loaded_joints(rms)
    if not keep:
        return None
    cols = [cand[g] for g in keep]
    slope = slope[:, keep][:, :, keep]
    a_prev = np.full((len(episode), len(cols)), np.nan)
    a_prev[1:] = lead_deg[:-1, cols]
    a_prev[1:][episode[1:] != episode[:-1]] = np.nan
    residual = a_prev - pose_deg[:, cols] - sag_deg[:, cols]
    return fit_sag_offsets(
        residual, slope, sag_deg[:, cols], lead_deg[:, cols], pose_deg[:, cols], episode, tuple(cols)
    )


def _with_sag(h: JointHealth, fit: SagFit | None, col: int, upd: float, cfg: HealthConfig) -> JointHealth:
    """An ``unobservable`` joint whose sag pattern puts the follower's offset past the threshold → ``offset``.

    The ``cfg.sag_confidence`` interval (99.9 %, Student t over the episodes) must lie beyond ``±threshold_deg``.
    The sag measures the
    follower's calibration against the gravity model's zero, not against the leader's: the reported offset
    assumes the leader's calibration is right (a leader's own offset leaves no trace in the sag).
    """
    if fit is None or col not in fit.joints or h.status != "unobservable":
        return h
    g = fit.joints.index(col)
    lo, hi = fit.interval(g, cfg.sag_confidence)
    if not (lo >= cfg.threshold_deg or hi <= -cfg.threshold_deg):
        return h
    est = float(fit.estimate[g])
    why = (
        f"the follower's gravity sag follows another angle: its calibration is {est:+.1f}° "
        f"[{lo:+.1f}, {hi:+.1f}] ({100 * cfg.sag_confidence:g} %) from the gravity model's zero (no range-end contact; the leader's "
        "calibration assumed right)"
    )
    return replace(h, status="offset", offset=est * upd, ci=(lo * upd, hi * upd), reasons=(why,))


def _num(x: float | None, scale: float = 1.0) -> float | None:
    return None if x is None or not math.isfinite(x) else round(x / scale, 4)


def _sag_json(fit: SagFit | None, col: int) -> dict[str, Any] | None:
    """The sag-pattern fit of one joint: the follower's offset against the gravity model's zero, degrees."""
    if fit is None or col not in fit.joints:
        return None
    g = fit.joints.index(col)
    lo, hi = fit.interval(g, 0.99)
    return {
        "offset_deg": round(float(fit.estimate[g]), 3),
        "ci99_deg": [round(lo, 3), round(hi, 3)],
        "se_deg": round(float(fit.se[g]), 3),
        "episodes": fit.episodes,
        "frames": fit.frames,
    }


def health_json(result: DatasetHealth) -> dict[str, Any]:
    """The report: ``{"joints": {NAME: {"offset_deg", "ci_deg", "status", "episodes", ...}}, ...}``.

    ``offset_deg`` and ``ci_deg`` are degrees (None where the dataset's units have no known degree scale; then
    ``offset`` and ``ci`` in ``units`` carry the numbers). The offset is the follower's calibration minus the
    leader's: what the follower reads minus what the leader reads at the same physical angle.
    """
    joints: dict[str, Any] = {}
    fit = result.sag
    for k, (h, units, _upd, eps, _) in enumerate(result.joints):
        deg = units == "degrees"
        scale = 1.0

        def ci(c: tuple[float, float] | None, s: float) -> list[float | None] | None:
            return None if c is None else [_num(c[0], s), _num(c[1], s)]

        joints[h.name] = {
            "offset_deg": _num(h.offset, scale) if deg else None,
            "ci_deg": ci(h.ci, scale) if deg else None,
            "status": h.status,
            "episodes": [
                {
                    "episode": e["episode"],
                    "offset_deg": _num(e["offset"], scale) if deg else None,
                    "ci_deg": ci(e["ci"], scale) if deg else None,
                    "status": e["status"],
                    "frames": e["frames"],
                    "jumps": [
                        {"frame": jp.frame, "size": round(jp.size, 4)}
                        for jp in h.jumps
                        if jp.episode == e["episode"]
                    ],
                }
                for e in eps
            ],
            "units": units,
            "offset": _num(h.offset),
            "ci": ci(h.ci, 1.0),
            "reasons": list(h.reasons),
            "model_band": round(h.band, 4),
            "range_ends": [
                {
                    "end": e.end,
                    "kind": e.kind,
                    "follower": round(e.follower, 4),
                    "leader": round(e.leader, 4),
                    "frames": e.frames,
                    "episodes": list(e.episodes),
                    "excess": _num(e.excess),
                    "band": _num(h.end_bands[0 if e.end == "lo" else 1]),
                    "raw_cap": _num(h.raw_caps[0 if e.end == "lo" else 1]),
                }
                for e in h.ends
            ],
            "jumps": [
                {"episode": jp.episode, "frame": jp.frame, "size": round(jp.size, 4)} for jp in h.jumps
            ],
            "sag": _sag_json(fit, k),
            "rest_level": None
            if h.rest is None
            else {"level": _num(h.rest.level), "typical": _num(h.rest.typical), "poses": len(h.rest.bins)},
        }
    return {
        "dataset": str(result.root),
        "frames": result.frames,
        "episodes": result.episodes,
        "offset_sign": "follower calibration minus leader calibration (follower reading minus leader reading "
        "at the same physical angle)",
        "flagged": list(result.flagged),
        "joints": joints,
    }
