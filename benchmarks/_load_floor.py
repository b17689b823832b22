"""The smallest calibration offset a follower's load reading against the gravity model reveals (issue 30 item 3).

One SO-101 joint on robocal's joint plant (``backends/sim/physics.py``: inertia, Coulomb friction and stiction,
viscous friction, gravity ``A·sin``) under the STS3215 firmware's position law at LeRobot's gains (P = 16,
D = 32: ``kp = P/1024·τ_stall`` per count, ``kd = D·0.005·τ_stall``, τ_stall 1.91 N·m). A session holds ``poses``
random poses, each approached from the previous one (so friction holds it from either side), and reads what a
monitor has at each: the position (4096 counts, ±1 count of noise) and ``Present_Load`` (0.1 % of τ_stall).

With a calibration offset ``e`` the joint is at ``θ = reading − e``; the monitor's model torque is
``A·sin(reading − hang)``, the servo holds ``A·sin(θ − hang) + f`` (``|f| ≤`` stiction). The offset is estimated
by least squares over the session, ``ê = −Σ c·r / Σ c²`` with ``c = A·cos(reading − hang)`` and ``r`` the load
minus the model. The floor is the smallest offset flagged in ≥ 95 % of sessions by the threshold that keeps
offset-free sessions ≤ 1 % flagged (their 99th percentile of ``|ê|``); a single reading's floor is
``stiction / A``.
"""

from __future__ import annotations

import math

import numpy as np

from robocal.backends.sim.physics import Drive, JointPlant, PlantParams

STALL_NM = 1.91
KP_NM_RAD = 16 / 1024 * STALL_NM * 4096 / (2 * math.pi)
KD_NMS_RAD = 32 * 0.005 * STALL_NM
LOAD_UNIT_NM = STALL_NM / 1000
COUNT_RAD = 2 * math.pi / 4096
JOINTS = {"shoulder_lift": 0.68, "elbow_flex": 0.45}
"""Gravity amplitude, N·m (the so101_new_calib URDF's masses, in the profile's search poses)."""
PLANT = PlantParams(
    inertia_kgm2=0.004,
    coulomb_nm=0.04,
    stiction_nm=0.06,
    viscous_nms_rad=0.02,
    stop_lower_rad=None,
    stop_upper_rad=None,
    counts_per_rev=0,
)
"""The simulated SO-101's nominal joint (``arm_physics.ARM_NOMINAL``) without stops: friction 0.04 / 0.06 N·m."""


def session(amplitude_nm: float, offset_rad: float, seed: int, poses: int = 20) -> float:
    """One session's offset estimate ``ê``, rad."""
    rng = np.random.default_rng(seed)
    plant = JointPlant(PLANT.__class__(**{**PLANT.__dict__, "gravity_nm": amplitude_nm}), seed=seed)
    hang = 0.0
    c_list, r_list = [], []
    for _ in range(poses):
        target = rng.uniform(-1.4, 1.4)  # ±80° about horizontal-hanging: the gravity torque's whole range
        plant.advance(0.6, Drive(KP_NM_RAD, KD_NMS_RAD, target, 0.0, 0.0, STALL_NM))
        theta = plant.q_rad
        reading = round((theta + offset_rad) / COUNT_RAD + rng.integers(-1, 2)) * COUNT_RAD
        load = round(plant.tau_motor_nm / LOAD_UNIT_NM) * LOAD_UNIT_NM
        model = amplitude_nm * math.sin(reading - hang)
        c_list.append(amplitude_nm * math.cos(reading - hang))
        r_list.append(load - model)
    c, r = np.array(c_list), np.array(r_list)
    return float(-np.dot(c, r) / np.dot(c, c))


def floor_table(seeds: int = 40, offsets_deg: tuple[float, ...] = (1, 2, 5, 10, 17)) -> list[str]:
    """The measured table: per joint the null spread, the threshold, detection per offset, the floor."""
    lines = []
    for joint, amp in JOINTS.items():
        null = np.abs([session(amp, 0.0, s) for s in range(seeds)])
        threshold = float(np.quantile(null, 0.99))
        rates = {}
        for off in offsets_deg:
            est = np.array([session(amp, math.radians(off), 1000 + s) for s in range(seeds)])
            rates[off] = float(np.mean(np.abs(est) > threshold))
        floor = next((o for o in offsets_deg if rates[o] >= 0.95), math.inf)
        cells = ", ".join(f"{o:g}°: {100 * rates[o]:.0f} %" for o in offsets_deg)
        lines.append(
            f"  {joint:13s} A = {amp:.2f} N·m: offset-free |ê| 99th pct {math.degrees(threshold):.2f}°; "
            f"flagged {cells}; floor {floor:g}° (one reading: {math.degrees(PLANT.stiction_nm / amp):.1f}°)"
        )
    return lines
