"""Datasheet numbers of the Feetech and Dynamixel servos: ratings per model, register units, status bits.

Shared by the simulated firmware (:mod:`robocal.backends.sim.servo_firmware`) and the stop-search drivers
(:mod:`robocal.workflows.autocal_servo`), which convert a torque cap into ``Goal_Current`` and a
``Present_Current`` back into torque with them.
"""

from __future__ import annotations

from dataclasses import dataclass

__all__ = ["OVERLOAD_BIT", "PWM_FULL", "RATINGS", "RPM_UNIT", "MotorRating"]

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


RATINGS: dict[str, MotorRating] = {
    "sts3215": MotorRating(1.91, 2.7, 0.0065),  # 7.4 V, 19.5 kg·cm
    "sts3250": MotorRating(4.9, 3.0, 0.0065),
    "sm8512bl": MotorRating(11.8, 7.0, 0.0065),
    "scs0009": MotorRating(0.23, 0.7, 0.0065),
    "xl330-m077": MotorRating(0.228, 1.47, 0.001, 1750),
    "xl330-m288": MotorRating(0.52, 1.47, 0.001, 1750),
    "xl430-w250": MotorRating(1.5, 1.4, 0.00269),  # no current sensing: no current modes
    "xc430-w150": MotorRating(1.4, 1.4, 0.00269),
    "xm430-w350": MotorRating(4.1, 2.3, 0.00269, 1193),
    "xm540-w270": MotorRating(10.6, 4.4, 0.00269, 2047),
}
"""Model → rating."""
