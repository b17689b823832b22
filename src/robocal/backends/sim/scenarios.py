"""Scenario flags of a simulated joint: what is special about it.

Soft, asymmetric or missing stops, an obstacle, a cable snag, stiction, gravity, backlash, an overload latch, a
motor that goes silent at the stop.

:class:`Scenario` turns nominal :class:`~.physics.PlantParams` (whose stops are the CAD/URDF angles) into the
parameters of one seeded joint; :func:`make_plant` builds the :class:`~.physics.JointPlant`. Both are also
importable from :mod:`.physics`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from typing import Literal

import numpy as np

from ...errors import UsageError
from .physics import JointPlant, OverloadLatch, PlantParams

__all__ = ["Scenario", "make_plant"]


@dataclass(frozen=True)
class Scenario:
    """What is special about one simulated joint (all off: a clean joint with the nominal stops).

    Attributes:
        soft_stop: Both stops 15 N·m/rad (3D-printed or rubber).
        asymmetric_stops: Each stop off its nominal angle by up to ±5° (independently), upper stop 0.3–1× as
            stiff as the lower one.
        missing_stop: ``"lower"``, ``"upper"`` or ``"both"`` (a continuous joint): that stop does not exist.
        obstacle: A block at 3/4 of the travel (between the midpoint and the upper stop).
        cable_snag: A cable that starts stretching at 60 % of the travel and reaches the search torque
            within the next 20 % of the travel (rising stiffness).
        stiction_ratio: Breakaway friction as a fraction of the search torque (≤ 0.8); running friction is
            half of it.
        gravity_nm: Gravity torque amplitude, largest at the midpoint of the stops (a loaded joint).
        backlash_rad: Gear play.
        overload_latch: Firmware overload protection: 0.1 s at ≥ 90 % of the search torque cuts the torque
            and sets the overload flag.
        silent_at_stop: The motor's replies are lost while it presses into a wall with more than half the
            search torque.
    """

    soft_stop: bool = False
    asymmetric_stops: bool = False
    missing_stop: Literal["none", "lower", "upper", "both"] = "none"
    obstacle: bool = False
    cable_snag: bool = False
    stiction_ratio: float = 0.0
    gravity_nm: float = 0.0
    backlash_rad: float = 0.0
    overload_latch: bool = False
    silent_at_stop: bool = False

    def __post_init__(self) -> None:
        if self.missing_stop not in ("none", "lower", "upper", "both"):
            raise UsageError(f"missing_stop is none, lower, upper or both, not {self.missing_stop!r}")
        if not 0.0 <= self.stiction_ratio <= 1.0:
            raise UsageError(f"stiction_ratio must be within [0, 1], not {self.stiction_ratio!r}")

    def params(self, nominal: PlantParams, *, search_torque_nm: float, seed: int = 0) -> PlantParams:
        """The plant parameters of this scenario around ``nominal`` (its stops are the CAD angles).

        Raises:
            UsageError: ``nominal`` lacks one of the stops the scenario places things between.
        """
        rng = np.random.default_rng(seed)
        lo, hi = nominal.stop_lower_rad, nominal.stop_upper_rad
        p = nominal
        if self.soft_stop:
            p = replace(p, stiffness_lower=15.0, stiffness_upper=15.0)
        if self.asymmetric_stops and lo is not None and hi is not None:
            d_lo, d_hi = np.radians(rng.uniform(-5.0, 5.0, size=2))
            p = replace(
                p,
                stop_lower_rad=lo + float(d_lo),
                stop_upper_rad=hi + float(d_hi),
                stiffness_upper=p.stiffness_upper * float(rng.uniform(0.3, 1.0)),
            )
        if self.obstacle or self.cable_snag or self.gravity_nm:
            if lo is None or hi is None:
                raise UsageError("obstacle, cable snag and gravity scenarios need both nominal stops")
            span = hi - lo
            if self.obstacle:
                p = replace(p, obstacle_rad=lo + 0.75 * span, obstacle_side=1)
            if self.cable_snag:
                x = 0.2 * span
                k1 = 0.2 * search_torque_nm / x
                k3 = (search_torque_nm - k1 * x) / x**3
                p = replace(
                    p, cable_rad=lo + 0.6 * span, cable_side=1, cable_k1_nm_rad=k1, cable_k3_nm_rad3=k3
                )
            if self.gravity_nm:
                p = replace(p, gravity_nm=self.gravity_nm, gravity_zero_rad=0.5 * (lo + hi) - 0.5 * math.pi)
        if self.stiction_ratio:
            s = self.stiction_ratio * search_torque_nm
            p = replace(p, stiction_nm=s, coulomb_nm=0.5 * s)
        if self.backlash_rad:
            p = replace(p, backlash_rad=self.backlash_rad)
        if self.missing_stop in ("lower", "both"):
            p = replace(p, stop_lower_rad=None)
        if self.missing_stop in ("upper", "both"):
            p = replace(p, stop_upper_rad=None)
        return p

    def overload(self, search_torque_nm: float) -> OverloadLatch | None:
        """The overload protection this scenario gives the firmware (None: off)."""
        return OverloadLatch(0.9 * search_torque_nm, 0.1) if self.overload_latch else None


def make_plant(
    scenario: Scenario,
    nominal: PlantParams,
    *,
    search_torque_nm: float,
    seed: int = 0,
    q0_rad: float | None = None,
) -> JointPlant:
    """A plant for ``scenario`` around ``nominal``, seeded (stop offsets and encoder noise).

    Args:
        scenario: What is special about the joint.
        nominal: Nominal physics; its stops are the CAD/URDF stop angles.
        search_torque_nm: The torque a stop search will push with (scales stiction, snag, faults).
        seed: Seed for the scenario's random draws and the encoder noise.
        q0_rad: Start position; default the nominal midpoint (or 0).
    """
    params = scenario.params(nominal, search_torque_nm=search_torque_nm, seed=seed)
    lo, hi = nominal.stop_lower_rad, nominal.stop_upper_rad
    if q0_rad is None:
        q0_rad = 0.5 * (lo + hi) if lo is not None and hi is not None else 0.0
    silent = 0.5 * search_torque_nm if scenario.silent_at_stop else None
    return JointPlant(
        params,
        seed=seed + 1,
        q0_rad=q0_rad,
        overload=scenario.overload(search_torque_nm),
        silent_above_nm=silent,
    )
