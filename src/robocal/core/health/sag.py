"""The follower's own calibration offsets from how its gravity sag varies with pose: weak evidence, honest interval.

A position servo with gain ``kp`` stands ``τ_g(θ)/kp`` from its goal, and gravity acts on the follower's *true*
angles ``θ = s − e`` (``s`` its readings, ``e`` its calibration offsets against the gravity model's zero). The
check's sag model evaluates the sag at the readings, so the residual ``a(t−1) − s(t) − sag(s)`` keeps
``Σ_k −∂sag_j/∂s_k · e_k``: every loaded joint's offset moves the sag of every joint (the shoulder's angle changes
the elbow's load). On LeRobot's SO-101 follower (``P_Coefficient`` 16) that is ~0.03° of residual per degree of
offset on shoulder_lift, less on the others.

Two effects of the same size correlate with that pattern and bias a plain fit by several degrees (measured on the
simulated SO-101: the plain fit's 95 % interval held 0 on only 40–80 % of offset-free sessions):

* **backlash**: the link rests on the side gravity pulls it, ``±backlash/2`` from the motor, so the reading
  jumps by the backlash where ``τ_g`` changes sign;
* **friction dead band**: the servo stops short of its goal on the side it came from (``±τ_coulomb/kp``).

Both enter the fit as nuisance columns per joint with unknown sizes (``sign τ_g`` and the sign of the joint's
last move). Frames: all loaded joints slow (``|Δa|`` under ``slow_deg`` for ``window`` frames: the lag is then
small), the residual under ``cut_deg`` (no stop contact), the reading not within ``edge_deg`` of the session's
extremes. The interval is a jackknife over episodes (frames of one episode are not independent: the effective
sample count is the number of episodes) with Student's t for ``episodes − 1`` degrees of freedom.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..arrays import BoolArray, FloatArray, IntArray

__all__ = ["SagFit", "SagFrames", "fit_sag_offsets", "last_direction", "loaded_joints", "t_quantile"]

_T975 = {
    1: 12.706,
    2: 4.303,
    3: 3.182,
    4: 2.776,
    5: 2.571,
    6: 2.447,
    7: 2.365,
    8: 2.306,
    9: 2.262,
    10: 2.228,
    12: 2.179,
    15: 2.131,
    20: 2.086,
    30: 2.042,
    60: 2.000,
}
_T995 = {
    1: 63.657,
    2: 9.925,
    3: 5.841,
    4: 4.604,
    5: 4.032,
    6: 3.707,
    7: 3.499,
    8: 3.355,
    9: 3.250,
    10: 3.169,
    12: 3.055,
    15: 2.947,
    20: 2.845,
    30: 2.750,
    60: 2.660,
}


_T9995 = {
    1: 636.62,
    2: 31.599,
    3: 12.924,
    4: 8.610,
    5: 6.869,
    6: 5.959,
    7: 5.408,
    8: 5.041,
    9: 4.781,
    10: 4.587,
    12: 4.318,
    15: 4.073,
    20: 3.850,
    30: 3.646,
    60: 3.460,
}


def t_quantile(level: float, dof: int) -> float:
    """Two-sided Student-t multiplier for ``level`` 0.95, 0.99 or 0.999 (the tabled dof at or below ``dof``).

    Raises:
        ValueError: Another level, or ``dof`` < 1.
    """
    table = {0.95: _T975, 0.99: _T995, 0.999: _T9995}.get(level)
    if table is None or dof < 1:
        raise ValueError(f"t_quantile: level {level} (0.95, 0.99 or 0.999), dof {dof} (≥ 1)")
    return table[max(k for k in table if k <= dof)]


@dataclass(frozen=True)
class SagFrames:
    """What the fit selects frames with (degrees).

    Attributes:
        slow_deg: Every loaded joint's leader moves less than this per frame over the window.
        window: Frames the leader must have been slow (the follower has settled).
        cut_deg: Residuals larger than this are contact or a fast move, not sag.
        edge_deg: Readings within this of the session's extremes are left out (stops).
        direction_step_deg: A move larger than this sets the joint's last direction.
    """

    slow_deg: float = 0.6
    window: int = 4
    cut_deg: float = 2.0
    edge_deg: float = 3.0
    direction_step_deg: float = 0.25


@dataclass(frozen=True)
class SagFit:
    """The follower's offsets against the gravity model's zero, from the sag pattern (degrees).

    Attributes:
        joints: Column indices (the dataset's) of the loaded joints fitted.
        estimate: ``(G,)`` offset estimates (reading minus true angle).
        se: ``(G,)`` jackknife standard errors over episodes.
        episodes: Episodes used (the jackknife's sample count).
        frames: Joint-frames used.
    """

    joints: tuple[int, ...]
    estimate: FloatArray
    se: FloatArray
    episodes: int
    frames: int

    def interval(self, k: int, level: float = 0.99) -> tuple[float, float]:
        """The ``level`` interval of fitted joint ``k`` (Student t, ``episodes − 1`` dof)."""
        half = t_quantile(level, self.episodes - 1) * float(self.se[k])
        return float(self.estimate[k]) - half, float(self.estimate[k]) + half


def last_direction(x: FloatArray, episode: IntArray, step: float) -> FloatArray:
    """Per frame, the sign of the reading's last move larger than ``step`` (0 before the first in an episode)."""
    out = np.zeros(x.shape)
    d, ref = 0.0, float(x[0]) if x.size else 0.0
    for t in range(x.size):
        v = float(x[t])
        if t and episode[t] != episode[t - 1]:
            d, ref = 0.0, v
        if v > ref + step:
            d, ref = 1.0, v
        elif v < ref - step:
            d, ref = -1.0, v
        elif (d > 0 and v > ref) or (d < 0 and v < ref):
            ref = v  # still moving the same way: the reversal is measured from the furthest point
        out[t] = d
    return out


def _rows(
    g: int, sel: BoolArray, slope: FloatArray, tau_sign: FloatArray, direction: FloatArray
) -> FloatArray:
    """Design rows of fitted joint ``g``: the offsets' columns, then backlash and friction columns per joint."""
    n_g = slope.shape[1]
    m = int(sel.sum())
    nuis = np.zeros((m, 2 * n_g))
    nuis[:, g] = tau_sign[sel, g]
    nuis[:, n_g + g] = direction[sel, g]
    out: FloatArray = np.concatenate([-slope[sel, g, :], nuis], axis=1)
    return out


def fit_sag_offsets(
    residual: FloatArray,
    slope: FloatArray,
    sag: FloatArray,
    action: FloatArray,
    state: FloatArray,
    episode: IntArray,
    joints: tuple[int, ...],
    frames: SagFrames | None = None,
) -> SagFit | None:
    """Least-squares offsets of the loaded joints with backlash and friction nuisances; jackknife over episodes.

    Args:
        residual: ``(N, G)`` ``a(t−1) − s(t) − sag`` of the loaded joints (NaN at an episode's first frame), degrees.
        slope: ``(N, G, G)`` ``∂ sag_j / ∂ s_k`` (degrees per degree).
        sag: ``(N, G)`` the model's sag (its sign is −sign τ_g).
        action: ``(N, G)`` leader readings, degrees.
        state: ``(N, G)`` follower readings, degrees.
        episode: ``(N,)`` episode index (frames of an episode consecutive).
        joints: The dataset's column index of each loaded joint (kept in the result).
        frames: Frame selection.

    Returns:
        The fit, or None (fewer than 3 episodes with
        frames, too few frames, or a singular fit).
    """
    fr = frames or SagFrames()
    n, n_g = residual.shape
    da = np.full((n, n_g), np.inf)
    da[1:] = np.abs(np.diff(action, axis=0))
    da[1:][episode[1:] != episode[:-1]] = np.inf
    base = np.ones(n, dtype=bool)
    for w in range(fr.window):  # the leader slow on every loaded joint over the window, all in one episode
        shifted = np.full((n, n_g), np.inf)
        shifted[w:] = da[: n - w]
        base &= np.all(shifted < fr.slow_deg, axis=1)
    use = np.zeros((n, n_g), dtype=bool)
    direction = np.zeros((n, n_g))
    for g in range(n_g):
        s = state[:, g]
        lo, hi = float(np.min(s)), float(np.max(s))
        use[:, g] = (
            base
            & (np.abs(np.nan_to_num(residual[:, g], nan=np.inf)) < fr.cut_deg)
            & (s > lo + fr.edge_deg)
            & (s < hi - fr.edge_deg)
        )
        direction[:, g] = last_direction(s, episode, fr.direction_step_deg)
    tau_sign = -np.sign(sag)
    eps = np.unique(episode[use.any(axis=1)])
    if eps.size < 3:
        return None
    rows = [_rows(g, use[:, g], slope, tau_sign, direction) for g in range(n_g)]
    b_all = [residual[use[:, g], g] for g in range(n_g)]
    ep_all = [episode[use[:, g]] for g in range(n_g)]
    a_mat, b_vec, e_vec = np.concatenate(rows), np.concatenate(b_all), np.concatenate(ep_all)

    def solve(keep: BoolArray) -> FloatArray | None:
        a, b = a_mat[keep], b_vec[keep]
        cols = np.any(a != 0, axis=0)  # a nuisance never excited (e.g. a joint that never reversed)
        if a.shape[0] < 10 * a.shape[1] or not cols[:n_g].all():
            return None
        ata = a[:, cols].T @ a[:, cols]
        if np.linalg.cond(ata) > 1e10:
            return None
        x: FloatArray = np.linalg.solve(ata, a[:, cols].T @ b)[:n_g]
        return x

    est = solve(np.ones(b_vec.size, dtype=bool))
    if est is None:
        return None
    jack = [v for v in (solve(e_vec != e) for e in eps) if v is not None]
    if len(jack) < 3:
        return None
    vals = np.stack(jack)
    k = len(jack)
    se = np.sqrt((k - 1) / k * np.sum((vals - vals.mean(axis=0)) ** 2, axis=0))
    if not np.all(np.isfinite(se)):
        return None
    return SagFit(joints, est, se, k, int(b_vec.size))


def loaded_joints(slope_rms: FloatArray, floor: float = 0.004) -> tuple[int, ...]:
    """Joints whose offset moves some joint's sag by at least ``floor`` degrees per degree (RMS over frames)."""
    return tuple(int(k) for k in np.flatnonzero(slope_rms >= floor))
