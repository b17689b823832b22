"""A simulated servo's winding temperature and supply voltage under load (an assumed, simple model).

Temperature: first order, ``dT/dt = (T_amb + ΔT_stall·(I/I_stall)² − T) / τ_th`` (copper loss ∝ I²): held at its
stall current a servo settles :data:`RISE_AT_STALL_C` above ambient with the time constant
:data:`TIME_CONSTANT_S`. Voltage: the supply sags by ``R_source·|I|`` (:data:`SOURCE_RESISTANCE_OHM`, supply and
wiring). Each update takes the current as held since the previous one and uses the exact solution, so the
result depends only on the simulated clock at the reads, not on how often they come. None of the three numbers
is from a datasheet: they are assumed (docs/sim.md), chosen so that a stalled servo warms by tens of °C over
minutes and its voltage drops by a few tenths of a volt.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

__all__ = ["RISE_AT_STALL_C", "SOURCE_RESISTANCE_OHM", "TIME_CONSTANT_S", "ServoThermal"]

RISE_AT_STALL_C = 50.0
"""Steady-state temperature rise with the stall current held, °C (assumed)."""
TIME_CONSTANT_S = 300.0
"""Thermal time constant of the winding and case, s (assumed)."""
SOURCE_RESISTANCE_OHM = 0.2
"""Resistance of the supply and its wiring, Ω (assumed)."""


@dataclass
class ServoThermal:
    """The temperature state of one servo (mutable: :meth:`update` moves it along the simulated clock).

    Attributes:
        ambient_c: Ambient (idle) temperature, °C.
        supply_v: Supply voltage with no current drawn, V.
        stall_current_a: The model's stall current, A.
        t_s: Simulated time of the last update, s.
        temperature_c: Temperature at ``t_s``, °C.
        voltage_v: Voltage at the last update, V.
    """

    ambient_c: float
    supply_v: float
    stall_current_a: float
    t_s: float
    temperature_c: float = math.nan
    voltage_v: float = math.nan

    def __post_init__(self) -> None:
        if math.isnan(self.temperature_c):
            self.temperature_c = self.ambient_c
        if math.isnan(self.voltage_v):
            self.voltage_v = self.supply_v

    def steady_c(self, current_a: float) -> float:
        """The temperature the servo settles at with ``current_a`` held, °C."""
        return self.ambient_c + RISE_AT_STALL_C * (current_a / self.stall_current_a) ** 2

    def update(self, t_s: float, current_a: float) -> tuple[float, float]:
        """Advance to ``t_s`` with ``current_a`` held since the last update.

        Returns:
            ``(temperature_c, voltage_v)`` at ``t_s``.
        """
        dt_s = max(0.0, t_s - self.t_s)
        target_c = self.steady_c(abs(current_a))
        self.temperature_c = target_c + (self.temperature_c - target_c) * math.exp(-dt_s / TIME_CONSTANT_S)
        self.t_s = max(self.t_s, t_s)
        self.voltage_v = max(0.0, self.supply_v - SOURCE_RESISTANCE_OHM * abs(current_a))
        return self.temperature_c, self.voltage_v
