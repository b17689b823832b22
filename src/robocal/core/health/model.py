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
for every frame; the dead band and the remaining noise set the model band (:func:`model_band`). How the sag varies
with an offset (:func:`sag_slopes`) is what :mod:`.sag` fits.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from ..arrays import FloatArray, IntArray
from ..gravity import GravityModel, gravity_torques

__all__ = ["fitted_sag", "model_band", "sag_residual_deg", "sag_slopes"]


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


def sag_slopes(
    model: GravityModel,
    joints: Sequence[str],
    state_deg: FloatArray,
    kp_nm_rad: Sequence[float],
    cols: Sequence[int],
    step_deg: float = 0.5,
) -> FloatArray:
    """``(N, G, G)`` ``∂ sag_j / ∂ s_k`` (degrees per degree) among the dataset columns ``cols``, central differences."""
    out = np.zeros((state_deg.shape[0], len(cols), len(cols)))
    for g, k in enumerate(cols):
        d = np.zeros(state_deg.shape[1])
        d[k] = step_deg
        up = sag_residual_deg(model, joints, state_deg + d, kp_nm_rad)
        down = sag_residual_deg(model, joints, state_deg - d, kp_nm_rad)
        out[:, :, g] = ((up - down) / (2 * step_deg))[:, list(cols)]
    return out


def fitted_sag(
    action: FloatArray,
    state: FloatArray,
    episode: IntArray,
    pose_deg: FloatArray,
    slow: float,
    edge: float,
    direction: FloatArray | None = None,
) -> FloatArray:
    """A joint's sag fitted from the data when no URDF masses give it: ``c0 + c1·sin q + c2·cos q`` of its own angle.

    A servo arm without masses in its URDF (LeRobot's Koch) still sags ``τ_g/kp``, and with the Koch's soft
    factory gains that is several degrees, varying with the pose. The shape ``A·sin(q + φ)`` of one link's
    gravity is fitted by least squares to ``action(t−1) − state(t)`` on slow frames (``|Δa|`` under ``slow`` twice
    running) away from the joint's extremes (``edge``: a stop holds the follower there), refitted without the
    frames past 4 robust sigmas. The phase is free, so the fit also absorbs what an offset does to the sag: it
    narrows the model band, it measures no offset. With ``direction`` a fourth column, the sign of the reading's
    last move, takes the friction dead band: a servo stops short of its goal on the side it came from (±1.3° on a
    Koch XL330 at its factory gain 400), which the sine alone leaves in the band.

    Args:
        action: ``(N,)`` leader values.
        state: ``(N,)`` follower values (same units).
        episode: ``(N,)`` episode index.
        pose_deg: ``(N,)`` the follower's angle in degrees (the sine's argument).
        slow: Slow-frame limit per frame, the values' units.
        edge: Margin from the extremes, the values' units.
        direction: ``(N,)`` the sign of each frame's last move (:func:`~.sag.last_direction`), or None.

    Returns:
        ``(N,)`` the fitted sag (``action − state`` at rest), or zeros when fewer than 30 frames qualify.
    """
    n = state.size
    prev = np.full(n, np.nan)
    prev[1:] = action[:-1]
    prev[1:][episode[1:] != episode[:-1]] = np.nan
    da = np.full(n, np.inf)
    da[1:] = np.abs(np.diff(action))
    da[1:][episode[1:] != episode[:-1]] = np.inf
    ok = (da < slow) & (np.roll(da, 1) < slow) & np.isfinite(prev)
    ok &= (state > np.min(state) + edge) & (state < np.max(state) - edge)
    q = np.radians(pose_deg)
    cols = [np.ones(n), np.sin(q), np.cos(q)]
    if direction is not None:
        cols.append(np.asarray(direction, dtype=np.float64))
    x = np.stack(cols, axis=1)
    y = prev - state
    if int(ok.sum()) < 30:
        return np.zeros(n)
    coef, *_ = np.linalg.lstsq(x[ok], y[ok], rcond=None)
    err = y[ok] - x[ok] @ coef
    sigma = 1.4826 * float(np.median(np.abs(err - np.median(err)))) + 1e-9
    keep = np.flatnonzero(ok)[np.abs(err) < 4 * sigma]
    if keep.size >= 30:
        coef, *_ = np.linalg.lstsq(x[keep], y[keep], rcond=None)
    out: FloatArray = x @ coef
    return out
