"""Joint physics of the simulated Lite: one :class:`~.physics.JointPlant` per joint, in real time when standalone.

The in-process ``sim:lite`` of ``sweep --auto`` (:mod:`robocal.workflows.autocal.sim`) and the standalone ``robocal
sim lite`` build their plants from the same nominal parameters (:func:`lite_plant_params`: the model's inertia,
friction as a fraction of the search torque, 600 N·m/rad stops at the joint limits, a 14-bit encoder). In process
the simulated clock moves with the host's sleeps; a standalone device has clients that do not sleep on its clock,
so :class:`RealtimePacer` keeps the clock level with the wall clock, integrating every joint under its motor's MIT
command every 5 ms and applying the motors' CAN timeouts on that clock.
"""

from __future__ import annotations

import math
import threading
import time
from collections.abc import Callable, Iterable
from contextlib import AbstractContextManager
from typing import TYPE_CHECKING, Any

from .physics import PlantParams, SimClock

if TYPE_CHECKING:
    from ..robstride.sim import SimMotor

__all__ = ["LITE_INERTIA_KGM2", "PACE_S", "RealtimePacer", "lite_plant_params"]

LITE_INERTIA_KGM2 = {"rs-02": 0.05, "rs-00": 0.03, "rs-05": 0.005}
"""Reflected inertia of a Lite joint by motor model (kg·m²); 0.02 for another model."""
PACE_S = 0.005
"""How often the standalone Lite integrates its joints (s)."""


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


class RealtimePacer:
    """Moves a :class:`~.physics.SimClock` with the wall clock (never behind it), integrating every motor's plant.

    Args:
        clock: The motors' simulated clock.
        motors: The simulated motors (each with a plant on ``clock``).
        locked: A context manager factory holding off the buses' threads while the joints are integrated.
        period_s: How often (s).
    """

    def __init__(
        self,
        clock: SimClock,
        motors: Iterable[SimMotor],
        locked: Callable[[], AbstractContextManager[Any]],
        period_s: float = PACE_S,
    ) -> None:
        self.clock, self.motors, self._locked, self.period_s = clock, list(motors), locked, period_s
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None

    def start(self) -> None:
        """Start pacing (a daemon thread)."""
        self._stop.clear()
        self._thread = threading.Thread(target=self._pace, name="sim-lite-pacer", daemon=True)
        self._thread.start()

    def stop(self) -> None:
        """Stop pacing."""
        self._stop.set()
        if self._thread is not None:
            self._thread.join(timeout=2.0)
            self._thread = None

    def tick(self, wall_elapsed_s: float, sim0_s: float) -> None:
        """Bring the clock to ``sim0_s + wall_elapsed_s`` and every joint and CAN timeout up to it."""
        with self._locked():
            behind = sim0_s + wall_elapsed_s - self.clock.now()
            if behind > 0:
                self.clock.advance(behind)
            now = self.clock.now()
            for m in self.motors:
                m.check_watchdog(now)  # integrates up to the trip under the old command first
                m.sync()

    def _pace(self) -> None:
        wall0, sim0 = time.monotonic(), self.clock.now()
        while not self._stop.wait(self.period_s):
            self.tick(time.monotonic() - wall0, sim0)
