"""Datasheet numbers of the Feetech and Dynamixel servos: ratings per model, register units, status bits.

Shared by the simulated firmware (:mod:`robocal.backends.sim.servo_firmware`) and the stop-search drivers
(:mod:`robocal.backends.servo_joint_driver`), which convert a torque cap into ``Goal_Current`` and a
``Present_Current`` back into torque with them.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

from ..core.motor_models import find_motor_model

__all__ = ["OVERLOAD_BIT", "PWM_FULL", "RATINGS", "RPM_UNIT", "MotorRating", "PositionLoop"]

PWM_FULL = 885
"""Dynamixel X ``Goal_PWM`` / ``PWM_Limit`` for 100 % duty."""
RPM_UNIT = 0.229
"""Dynamixel velocity unit (rev/min per ``Goal_Velocity`` / ``Present_Velocity`` unit)."""
OVERLOAD_BIT = 0x20
"""Bit 5 of Feetech ``Status`` and of Dynamixel ``Hardware_Error_Status``: the overload protection tripped."""


@dataclass(frozen=True)
class MotorRating:
    """Datasheet numbers of a servo model.

    Attributes:
        stall_torque_nm: Stall torque at the nominal voltage.
        stall_current_a: Stall current.
        current_unit_a: One unit of ``Present_Current`` / ``Goal_Current``.
        current_limit: Factory ``Current_Limit`` (Dynamixel; 0 where there is none: no current sensing, no
            current-based modes).
    """

    stall_torque_nm: float
    stall_current_a: float
    current_unit_a: float
    current_limit: int = 0

    @property
    def kt_nm_a(self) -> float:
        """Torque per ampere."""
        return self.stall_torque_nm / self.stall_current_a


def _stall(model: str) -> float:
    """The stall torque of a bus model from robocal's motor table (:mod:`robocal.core.motor_models`)."""
    found = find_motor_model(model)
    assert found is not None, model
    return found.stall_nm


RATINGS: dict[str, MotorRating] = {
    "sts3215": MotorRating(_stall("sts3215"), 2.7, 0.0065),  # 7.4 V, 19.5 kg·cm (the 12 V C018 answers the same)
    "sts3250": MotorRating(_stall("sts3250"), 3.0, 0.0065),
    "sm8512bl": MotorRating(_stall("sm8512bl"), 7.0, 0.0065),
    "scs0009": MotorRating(_stall("scs0009"), 0.7, 0.0065),
    "xl330-m077": MotorRating(_stall("xl330-m077"), 1.47, 0.001, 1750),
    "xl330-m288": MotorRating(_stall("xl330-m288"), 1.47, 0.001, 1750),
    "xl430-w250": MotorRating(_stall("xl430-w250"), 1.4, 0.00269),  # no current sensing: no current modes
    "xc430-w150": MotorRating(_stall("xc430-w150"), 1.4, 0.00269),
    "xm430-w350": MotorRating(_stall("xm430-w350"), 2.3, 0.00269, 1193),
    "xm540-w270": MotorRating(_stall("xm540-w270"), 4.4, 0.00269, 2047),
}
"""Bus model → rating (stall torques from :data:`robocal.core.motor_models.MOTOR_MODELS`, where their sources are)."""


@dataclass(frozen=True)
class PositionLoop:
    """A vendor's position loop as robocal models it (one per vendor home, ``backends/<vendor>/gains.py``).

    Attributes:
        gains_nm_rad: ``(model, p, d, ticks_per_turn=4096) → (kp N·m/rad, kd N·m·s/rad)`` for the loop's P and D
            gain registers.
        factory_gains: ``model → (P, I, D)`` as the servo leaves the factory (KeyError: no table for the model).
    """

    gains_nm_rad: Callable[..., tuple[float, float]]
    factory_gains: Callable[[str], tuple[int, int, int]]
