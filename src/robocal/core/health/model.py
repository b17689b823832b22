"""What a correctly calibrated follower does differently from its leader: the model the dataset check subtracts.

In teleoperation the follower is commanded to the leader's number in its own calibration frame; ``action − state``
is then not zero even for a perfect calibration:

* **gravity sag**: a position servo with gain ``kp`` holding against gravity torque ``τ_g`` stands
  ``τ_g/kp`` away from its goal, so ``action − state = −τ_g(q)/kp`` (radians) at rest. LeRobot's SO follower
  (``P_Coefficient`` 16 on a 1.91 N·m STS3215, robocal's Feetech gain scaling) has ``kp`` ≈ 19.5 N·m/rad: 0.6–1.8°
  of sag on shoulder_lift and elbow_flex, depending on the pose;
* **friction dead band**: the servo stops anywhere within ``±τ_stiction/kp`` of the goal;
* **lag**: the reading of frame ``t`` is taken before action ``t`` is sent; the follower tracks ``action(t−1)``
  with a time constant of a few frames, so the residual grows with speed (the check uses slow frames).

:func:`sag_residual_deg` evaluates the sag term from a :class:`~robocal.core.gravity.GravityModel` (a URDF's masses)
for every frame; the dead band and the remaining noise set the model band (:func:`model_band`).
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from ..arrays import BoolArray, FloatArray, IntArray
from ..gravity import GravityModel, gravity_torques

__all__ = ["feetech_kp_nm_rad", "model_band", "sag_offset_fit", "sag_residual_deg"]


def feetech_kp_nm_rad(p_coefficient: int, stall_torque_nm: float, ticks_per_turn: int = 4096) -> float:
    """Position stiffness of a Feetech STS servo: ``P/1024 · τ_stall`` per tick of error, in N·m/rad."""
    return p_coefficient / 1024 * stall_torque_nm * ticks_per_turn / math.tau


def sag_residual_deg(
    model: GravityModel, joints: Sequence[str], state_deg: FloatArray, kp_nm_rad: Sequence[float]
) -> FloatArray:
    """The sag part of ``action − state`` for a correctly calibrated follower, degrees.

    Args:
        model: The arm's gravity model (its joint zero and signs those of the dataset's degrees).
        joints: Dataset joint names, column order; joints absent from the model get no sag.
        state_deg: ``(N, J)`` follower readings, degrees (the pose gravity acts on).
        kp_nm_rad: Position gain per joint (``inf`` or 0: no sag).

    Returns:
        ``(N, J)`` expected ``action − state`` at rest, degrees.
    """
    names = model.joint_names
    q = np.zeros((state_deg.shape[0], len(names)))
    cols = [(j, names.index(n)) for j, n in enumerate(joints) if n in names]
    for j, m in cols:
        q[:, m] = np.radians(np.nan_to_num(state_deg[:, j]))
    tau = gravity_torques(model, q) if len(q) else np.zeros_like(q)
    out = np.zeros(state_deg.shape)
    for j, m in cols:
        kp = float(kp_nm_rad[j])
        if kp > 0 and math.isfinite(kp):
            out[:, j] = -np.degrees(tau[:, m] / kp)
    return out


def model_band(residual: FloatArray, floor: float) -> float:
    """Half-width of the band a correct calibration's slow-frame residual stays in: ``max(floor, 4·1.4826·MAD)``.

    Args:
        residual: Slow-frame residuals after the sag model (one joint).
        floor: Smallest band (the dead band plus the encoder's tick), same units.
    """
    if residual.size == 0:
        return floor
    med = float(np.median(residual))
    mad = float(np.median(np.abs(residual - med)))
    return max(floor, 4.0 * 1.4826 * mad)


def sag_offset_fit(
    residual: FloatArray, slope: FloatArray, episode: IntArray, mask: BoolArray
) -> tuple[FloatArray, FloatArray] | None:
    """The follower's own offsets against the gravity model's zero, from how its sag varies with pose (weak).

    Sag follows the follower's *true* angles ``s − e_F``; the model evaluates it at the readings ``s``, so the
    residual of joint ``j`` left after the model is ``Σ_k −∂sag_j/∂s_k · e_F,k``: every loaded joint's offset
    moves every joint's sag (the shoulder's angle changes the elbow's load). A joint least-squares fit over the
    slow frames of all the joints, with a jackknife interval over episodes (frames of one episode are not
    independent).

    Args:
        residual: ``(N, G)`` residual after the sag model of the G loaded joints (NaN where not used), degrees.
        slope: ``(N, G, G)`` ``∂ sag_j / ∂ angle_k`` (degrees per degree).
        episode: ``(N,)`` episode index.
        mask: ``(N, G)`` frames to use per joint.

    Returns:
        ``(estimates (G,), half-widths (G,) of ~95 % intervals)`` in degrees, or None (fewer than 3 episodes, or a
        singular fit).
    """
    use = np.asarray(mask, dtype=bool) & np.isfinite(residual)
    eps = np.unique(episode[use.any(axis=1)])
    if eps.size < 3:
        return None

    def fit(rows: np.ndarray) -> FloatArray | None:
        sel = use & rows[:, None]
        a = -slope[sel]  # (M, G): frames × joints selected, each a row of the Jacobian
        b = residual[sel]
        if a.shape[0] < 10 * a.shape[1]:
            return None
        ata = a.T @ a
        if np.linalg.cond(ata) > 1e8:
            return None
        out: FloatArray = np.linalg.solve(ata, a.T @ b)
        return out

    est = fit(np.ones(len(episode), dtype=bool))
    if est is None:
        return None
    jack = [v for v in (fit(episode != e) for e in eps) if v is not None]
    if len(jack) < 2:
        return None
    vals = np.stack(jack)
    n = len(jack)
    se = np.sqrt((n - 1) / n * np.sum((vals - vals.mean(axis=0)) ** 2, axis=0))
    return est, 2.0 * se
