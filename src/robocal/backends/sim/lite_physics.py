"""Joint physics of the simulated Lite: one :class:`~.physics.JointPlant` per joint, in real time when standalone.

The in-process ``sim:lite`` of ``sweep --auto`` (:mod:`robocal.workflows.autocal.sim`) and the standalone ``robocal
sim lite`` build their plants from the same nominal parameters (:func:`lite_plant_params`: the model's inertia,
friction as a fraction of the search torque, 600 N·m/rad stops at the joint limits, a 14-bit encoder). In process
the simulated clock moves with the host's sleeps; a standalone device has clients that do not sleep on its clock,
so :class:`~.pacer.RealtimePacer` keeps the clock level with the wall clock, integrating every joint under its motor's MIT
command every 5 ms and applying the motors' CAN timeouts on that clock.
"""

from __future__ import annotations

import math

from .physics import PlantParams

__all__ = ["LITE_INERTIA_KGM2", "lite_plant_params"]

LITE_INERTIA_KGM2 = {"rs-02": 0.05, "rs-00": 0.03, "rs-05": 0.005}
"""Reflected inertia of a Lite joint by motor model (kg·m²); 0.02 for another model."""


def lite_plant_params(model: str, lower_rad: float, upper_rad: float, cap_nm: float) -> PlantParams:
    """The nominal physics of a Lite joint driven by a ``model`` motor with stops at ``lower``/``upper``.

    Friction scales with the search torque ``cap_nm`` (stiction 5 %, Coulomb 3 %, viscous 2 % per rad/s), so a
    search at that cap moves it; the stops are 600 N·m/rad springs; the encoder has 16384 counts and 0.01° noise.
    """
    return PlantParams(
        inertia_kgm2=LITE_INERTIA_KGM2.get(model, 0.02),
        coulomb_nm=0.03 * cap_nm,
        stiction_nm=0.05 * cap_nm,
        viscous_nms_rad=0.02 * cap_nm,
        stop_lower_rad=lower_rad,
        stop_upper_rad=upper_rad,
        stiffness_lower=600.0,
        stiffness_upper=600.0,
        counts_per_rev=16384,
        noise_rad=math.radians(0.01),
    )
