"""Many position-controlled servo joints at once: the joint plant of :mod:`.physics`, vectorised with numpy.

:class:`~.physics.JointPlant` integrates one joint in Python, one 0.5 ms step at a time: right for a simulated
servo on a bus, far too slow for the hundreds of teleoperation sessions a health benchmark needs. This module
integrates the same model for an array of joints (lanes × joints) in lockstep:

* motor law ``τ_m = clip(kp·(q_ref − q) − kd·v, ±τ_max)`` (the Feetech STS position law of
  :mod:`.servo_firmware` with LeRobot's ``P_Coefficient`` / ``D_Coefficient``, or a Dynamixel's
  ``Position_P_Gain`` / ``Position_D_Gain``, as gains in N·m/rad and N·m·s/rad);
* gravity ``τ_g(q)`` from a callback (per frame, the whole arm's pose: the URDF's masses), a stop at each end
  (a spring ``k`` with damping ``2ζ√(kJ)`` that only pushes), viscous, Coulomb and breakaway friction (the plant's
  stuck/sliding rule), backlash (the link sits ``±backlash/2`` from the motor, on the side gravity pulls it);
* the same semi-implicit step as :meth:`~.physics.JointPlant.step` (the stiffness of the motor law and of a stop
  taken implicitly), so a larger step (a few ms) stays stable;
* readings: the link angle, plus Gaussian noise, quantised to the encoder's ticks.

``tests/dataset/test_health_sim.py`` checks it against :class:`~.physics.JointPlant` step for step.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from ...core.arrays import FloatArray

__all__ = ["GravityFn", "PlantArrays", "simulate_tracking"]

GravityFn = Callable[[FloatArray], FloatArray]
"""Link angles ``(L, J)`` rad → gravity torque ``(L, J)`` N·m (positive towards +q)."""


@dataclass(frozen=True)
class PlantArrays:
    """Per-joint physics of a follower arm, each an ``(J,)`` array (SI units, joint frame).

    Attributes:
        kp_nm_rad: Position gain.
        kd_nms_rad: Velocity (D) gain.
        tau_max_nm: Torque cap.
        inertia_kgm2: Reflected inertia.
        coulomb_nm: Running friction.
        stiction_nm: Breakaway friction (≥ ``coulomb_nm``).
        viscous_nms_rad: Viscous friction.
        backlash_rad: Total gear play.
        stop_lo_rad: Lower stop (``-inf``: none).
        stop_hi_rad: Upper stop (``inf``: none).
        stop_k_nm_rad: Stop stiffness.
        noise_rad: Encoder noise σ.
        counts_per_rev: Encoder ticks per turn.
    """

    kp_nm_rad: FloatArray
    kd_nms_rad: FloatArray
    tau_max_nm: FloatArray
    inertia_kgm2: FloatArray
    coulomb_nm: FloatArray
    stiction_nm: FloatArray
    viscous_nms_rad: FloatArray
    backlash_rad: FloatArray
    stop_lo_rad: FloatArray
    stop_hi_rad: FloatArray
    stop_k_nm_rad: FloatArray
    noise_rad: FloatArray
    counts_per_rev: int = 4096


def _walls(
    p: PlantArrays, x: FloatArray, v: FloatArray, c_stop: FloatArray
) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Stop torque on the link at (x, v), its stiffness and damping (a stop pushes, never pulls)."""
    pen_hi = x - p.stop_hi_rad
    pen_lo = p.stop_lo_rad - x
    t_hi = -(p.stop_k_nm_rad * pen_hi + c_stop * v)
    t_lo = p.stop_k_nm_rad * pen_lo - c_stop * v
    on_hi = (pen_hi > 0) & (t_hi <= 0)
    on_lo = (pen_lo > 0) & (t_lo >= 0)
    tau = np.where(on_hi, t_hi, 0.0) + np.where(on_lo, t_lo, 0.0)
    on = on_hi | on_lo
    return tau, np.where(on, p.stop_k_nm_rad, 0.0), np.where(on, c_stop, 0.0)


def simulate_tracking(
    goal_rad: FloatArray,
    params: PlantArrays,
    gravity: GravityFn | None,
    *,
    fps: float,
    substeps: int = 8,
    q0_rad: FloatArray | None = None,
    rng: np.random.Generator | None = None,
    stop_torque_out: FloatArray | None = None,
) -> FloatArray:
    """Drive every lane's joints to a goal that changes once per frame; return the readings at each frame.

    Frame ``t``'s reading is taken at the start of the frame, before goal ``t`` is sent (LeRobot records the
    observation, then sends the action): the follower at frame ``t`` has been tracking goal ``t − 1``.

    Args:
        goal_rad: ``(L, T, J)`` goals (the follower's own frame, rad).
        params: The joints' physics.
        gravity: Link angles ``(L, J)`` → gravity torque; evaluated once per frame. ``None``: no gravity.
        fps: Frames per second.
        substeps: Integration steps per frame.
        q0_rad: ``(L, J)`` start angles (default: the first goal).
        rng: Noise source (default: seeded 0).
        stop_torque_out: ``(L, T, J)`` filled, when given, with the stops' spring torque on the link at the end of
            each frame's steps, N·m (negative: the upper stop holds it, positive: the lower; 0: free). A truth of
            the simulation (how hard the follower was held by a stop), never in a dataset.

    Returns:
        ``(L, T, J)`` encoder readings of the link, rad, quantised.
    """
    p = params
    lanes, frames, joints = goal_rad.shape
    rng = rng or np.random.default_rng(0)
    dt = 1.0 / (fps * substeps)
    j = p.inertia_kgm2
    c_stop = 2 * 0.5 * np.sqrt(p.stop_k_nm_rad * j)
    q = np.array(goal_rad[:, 0, :] if q0_rad is None else q0_rad, dtype=np.float64)
    v = np.zeros_like(q)
    stuck = np.ones(q.shape, dtype=bool)
    half = 0.5 * p.backlash_rad
    out = np.empty((lanes, frames, joints))
    res = math.tau / p.counts_per_rev
    tau_g = np.zeros_like(q)
    q_ref = q.copy()
    for t in range(frames):
        link = q + half * np.sign(tau_g)
        reading = link + rng.normal(0.0, 1.0, q.shape) * p.noise_rad
        out[:, t, :] = np.round(reading / res) * res
        q_ref = goal_rad[:, t, :]
        if gravity is not None:
            tau_g = gravity(link)
        for _ in range(substeps):
            link = q + half * np.sign(tau_g)
            raw = p.kp_nm_rad * (q_ref - q) - p.kd_nms_rad * v
            sat = np.abs(raw) >= p.tau_max_nm
            tau_m = np.where(sat, np.sign(raw) * p.tau_max_nm, raw)
            k_m = np.where(sat, 0.0, p.kp_nm_rad)
            c_m = np.where(sat, 0.0, p.kd_nms_rad)
            tau_w, k_w, c_w = _walls(p, link, v, c_stop)
            f = tau_m + tau_g + tau_w - p.viscous_nms_rad * v
            breaks = ~stuck | (np.abs(f) > p.stiction_nm)
            fric = -p.coulomb_nm * np.where(stuck, np.sign(f), np.sign(v))
            big_k = k_m + k_w
            big_d = c_m + c_w + p.viscous_nms_rad
            v1 = (j * v / dt + f + fric + big_d * v) / (j / dt + big_k * dt + big_d)
            direction = np.where(v != 0.0, v, f)
            stop_now = (v1 * direction < 0) | (v1 == 0.0)
            v1 = np.where(breaks & ~stop_now, v1, 0.0)
            q = np.where(breaks, q + v1 * dt, q)
            stuck = ~breaks | stop_now
            v = v1
        if stop_torque_out is not None:
            link = q + half * np.sign(tau_g)
            spring = p.stop_k_nm_rad * (np.maximum(0.0, p.stop_lo_rad - link) - np.maximum(0.0, link - p.stop_hi_rad))
            stop_torque_out[:, t, :] = spring
    return out
