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

from ..arrays import FloatArray
from ..gravity import GravityModel, gravity_torques

__all__ = ["feetech_kp_nm_rad", "model_band", "sag_residual_deg"]


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
