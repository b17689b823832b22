"""The simulated Feetech STS/SCS servo: its firmware's control law and protection, and how its bus behaves.

Feetech STS/SCS, ``Operating_Mode`` 0 (position): ``τ = clip(P/1024·τ_stall·e − D·0.005·τ_stall·ω,
±τ_stall·Torque_Limit/1000)`` with ``P_Coefficient``, ``D_Coefficient``; the setpoint moves toward
``Goal_Position`` at ``Goal_Velocity`` ticks/s (0: at once). ``Operating_Mode`` 1 (velocity): a velocity loop to
the signed ``Goal_Velocity`` (ticks/s), same torque cap. Overload protection: ``|τ| ≥ τ_stall·Overload_Torque %``
for ``Protection_Time``·10 ms sets ``Status`` bit 5 and limits the torque to ``Protective_Torque %`` until the
torque is switched off. ``Present_Load`` is τ/τ_stall in 0.1 % (sign bit 10), ``Present_Current`` in 6.5 mA,
``Present_Velocity`` in ticks/s, ``Moving`` while |ω| > 20 ticks/s or the setpoint is travelling.
``Present_Temperature`` (°C) rises with the current and ``Present_Voltage`` (0.1 V) sags with it
(:class:`~robocal.backends.sim.servo_thermal.ServoThermal`, assumed; from the factory 25 °C and 7.4 V).
The shared part (frames, ramp, integration) is :class:`~robocal.backends.sim.servo_firmware.ServoFirmware`.
"""

from __future__ import annotations

import math

from ...core.lerobot import encode_sign_magnitude
from ..servo_ratings import OVERLOAD_BIT
from ..sim.physics import OverloadLatch
from ..sim.servo_firmware import ServoFirmware
from ..sim.servo_kind import SimServoKind
from ..sim.servo_packets import feetech_status, parse_feetech
from ..sim.servo_thermal import ServoThermal
from .gains import position_gains_nm_rad
from .tables import FEETECH_MODELS

__all__ = ["FEETECH_SIM", "FeetechFirmware"]


class FeetechFirmware(ServoFirmware):
    """The Feetech STS/SCS firmware (see the module docstring)."""

    TORQUE_OFF_CLEARS_LATCH = True
    thermal: ServoThermal
    """Temperature and voltage under load (started from the power-on registers)."""

    def _power_on_registers(self) -> None:
        s = self.servo
        self.thermal = ServoThermal(
            ambient_c=float(self._reg("Present_Temperature") or 25),
            supply_v=(self._reg("Present_Voltage") or 74) / 10,
            stall_current_a=self.rating.stall_current_a,
            t_s=self.clock.now(),
        )
        if "Torque_Limit" in s.table:
            for name, value in (
                ("Max_Torque_Limit", 1000),
                ("Torque_Limit", 1000),
                ("P_Coefficient", 32),
                ("D_Coefficient", 32),
                ("Protective_Torque", 20),
                ("Protection_Time", 200),
                ("Overload_Torque", 80),
            ):
                s.set_reg(name, value)

    def _position_gains(self) -> tuple[float, float]:
        p, d = self._reg("P_Coefficient", 32), self._reg("D_Coefficient", 32)
        return position_gains_nm_rad(self.servo.model, p, d, self.res)

    def _cap(self) -> float:
        return self.rating.stall_torque_nm * min(1000, self._reg("Torque_Limit", 1000)) / 1000

    def _vendor_overload(self) -> OverloadLatch:
        r = self.rating
        return OverloadLatch(
            r.stall_torque_nm * self._reg("Overload_Torque", 80) / 100,
            self._reg("Protection_Time", 200) * 0.01,
            r.stall_torque_nm * self._reg("Protective_Torque", 20) / 100,
        )

    def _speed_register(self) -> str:
        return "Goal_Velocity" if "Goal_Velocity" in self.servo.table else "Goal_Speed"

    def _velocity_ref_rad_s(self) -> float:
        return self._reg(self._speed_register()) * math.tau / self.res

    def _ramp_speed_ticks_s(self) -> float:
        return float(abs(self._reg(self._speed_register())))

    def _position_law(self, mode: int) -> bool:
        return mode == 0

    def error_byte(self) -> int:
        """The ``Status`` bits of a status packet (bit 5 while the overload latch stands)."""
        return OVERLOAD_BIT if self.plant.latched else 0

    def _refresh_vendor(self, tau_nm: float, v_ticks_s: float) -> bool | None:
        s, r = self.servo, self.rating
        if "Present_Load" in s.table:
            load = max(-1000, min(1000, round(tau_nm / r.stall_torque_nm * 1000)))
            self._raw("Present_Load", encode_sign_magnitude(load, 10) if not s.big_endian else abs(load))
        if "Present_Current" in s.table:
            self._raw("Present_Current", min(0x7FFF, round(abs(tau_nm) / r.kt_nm_a / r.current_unit_a)))
        temp_c, volt_v = self.thermal.update(self.clock.now(), tau_nm / r.kt_nm_a)
        if "Present_Temperature" in s.table:
            self._raw("Present_Temperature", min(255, round(temp_c)))
            self._raw("Present_Voltage", min(255, round(volt_v * 10)))
        name = "Present_Velocity" if "Present_Velocity" in s.table else "Present_Speed"
        v = max(-32767, min(32767, round(v_ticks_s)))
        self._raw(name, encode_sign_magnitude(v, 15) if not s.big_endian else v & 0xFFFF)
        if "Status" in s.table:
            status = self._reg("Status") & ~OVERLOAD_BIT
            s.set_reg("Status", status | (OVERLOAD_BIT if self.plant.latched else 0))
        return None


FEETECH_SIM = SimServoKind(
    vendor="feetech",
    models=FEETECH_MODELS,
    power_on=(
        ("Lock", 1),
        ("Baud_Rate", 0),
        ("Firmware_Major_Version", 3),
        ("Firmware_Minor_Version", 10),
    ),
    baud_rates={0: 1_000_000, 1: 500_000, 2: 250_000, 3: 128_000, 4: 115_200, 5: 57_600, 6: 38_400, 7: 19_200},
    factory_baud=0,  # 1 Mbit/s as shipped
    twos_complement=(),
    clamps_goal=True,
    single_turn_mode=None,
    address_bytes=1,
    parse=parse_feetech,
    status=feetech_status,
    ping_reports_model=False,
    reboot=False,
    unknown_instruction_error=0,
    eeprom_locked_by_torque=False,
    firmware=FeetechFirmware,
    status_level="Response_Status_Level",
    reply_levels={0x01: 0, 0x02: 0, 0x82: 0},  # level 0: PING and READ only; 1: all (Feetech's table)
    full_reply_level=1,
    set_middle=128,
)
"""How simulated Feetech servos behave on the bus and in their firmware."""
