"""The simulated Dynamixel X servo: its firmware's control law and protection, and how its bus behaves.

``Operating_Mode`` 5 (current-based position): ``τ = clip(kt·i_unit·(P/128·e − D/16·ω_ms),
±kt·i_unit·min(|Goal_Current|, Current_Limit))`` with ``Position_P_Gain``, ``Position_D_Gain`` (``ω_ms`` in
ticks/ms), setpoint ramped at ``Profile_Velocity`` (0.229 rev/min; 0: at once); modes 3/4 the same law capped
at ``τ_stall·min(PWM_Limit, |Goal_PWM|)/885`` (``Goal_PWM`` also limits mode 5); mode 1 velocity, mode 0 current
(``Goal_Current``), mode 16 PWM. ``Present_Current`` in the model's current unit, ``Present_Velocity`` in
0.229 rev/min, ``Moving`` above ``Moving_Threshold``. Overload: ≥ 95 % of the mode's maximum output for 1 s sets
``Hardware_Error_Status`` bit 5, switches the torque off and keeps it off (the alert bit 0x80 in every status
packet) until a REBOOT. ``Present_Temperature`` (°C) rises with the current and ``Present_Input_Voltage``
(0.1 V) sags with it (:class:`~robocal.backends.sim.servo_thermal.ServoThermal`, assumed; from 25 °C and the
model's assumed supply in :mod:`~robocal.backends.sim.servo_defaults`, 12 V where it has none). The shared part (frames, ramp, integration) is
:class:`~robocal.backends.sim.servo_firmware.ServoFirmware`.
"""

from __future__ import annotations

import math

from ...core.lerobot import encode_twos_complement
from ..servo_ratings import OVERLOAD_BIT, PWM_FULL, RPM_UNIT
from ..sim.physics import Drive, OverloadLatch
from ..sim.servo_firmware import ServoFirmware
from ..sim.servo_kind import SimServoKind
from ..sim.servo_packets import dynamixel_status, parse_dynamixel
from ..sim.servo_thermal import ServoThermal
from .gains import position_gains_nm_rad
from .tables import DYNAMIXEL_MODELS

__all__ = ["DYNAMIXEL_SIM", "DynamixelFirmware"]


class DynamixelFirmware(ServoFirmware):
    """The Dynamixel X firmware (see the module docstring)."""

    LATCH_SWITCHES_TORQUE_OFF = True
    thermal: ServoThermal
    """Temperature and voltage under load (started from the power-on registers)."""

    def _power_on_registers(self) -> None:
        s = self.servo
        self.thermal = ServoThermal(
            ambient_c=float(self._reg("Present_Temperature") or 25),
            supply_v=(self._reg("Present_Input_Voltage") or 120) / 10,
            stall_current_a=self.rating.stall_current_a,
            t_s=self.clock.now(),
        )
        s.set_reg("Current_Limit", self.rating.current_limit)
        s.set_reg("Goal_Current", self.rating.current_limit)
        s.set_reg("PWM_Limit", PWM_FULL)
        s.set_reg("Goal_PWM", PWM_FULL)  # RAM: PWM_Limit at power-on
        if not self._reg("Position_P_Gain"):  # a model without a factory table (its page was not read)
            s.set_reg("Position_P_Gain", 800)
        s.set_reg("Moving_Threshold", 10)
        if not self._reg("Shutdown"):  # likewise (the factory's: 53 on the XL330s, 52 on the X430s)
            s.set_reg("Shutdown", 0x34)

    @property
    def _sign(self) -> float:
        return -1.0 if self._reg("Drive_Mode") & 1 else 1.0

    def _position_gains(self) -> tuple[float, float]:
        return position_gains_nm_rad(self.servo.model, self._reg("Position_P_Gain"), self._reg("Position_D_Gain"), self.res)

    def _cap(self) -> float:
        r = self.rating
        pwm = min(PWM_FULL, self._reg("PWM_Limit"))
        if self._reg("Operating_Mode") in (3, 4, 5):  # Goal_PWM limits the output of the position modes
            pwm = min(pwm, abs(self._reg("Goal_PWM")))
        pwm_cap = r.stall_torque_nm * pwm / PWM_FULL
        if self._reg("Operating_Mode") in (0, 5):
            amps = min(abs(self._reg("Goal_Current")), self._reg("Current_Limit")) * r.current_unit_a
            return min(pwm_cap, amps * r.kt_nm_a)
        return pwm_cap

    def _vendor_overload(self) -> OverloadLatch:
        r = self.rating
        return OverloadLatch(0.95 * r.stall_torque_nm * min(1.0, self._reg("PWM_Limit") / PWM_FULL), 1.0, 0.0)

    def _velocity_ref_rad_s(self) -> float:
        return self._reg("Goal_Velocity") * RPM_UNIT / 60 * math.tau

    def _ramp_speed_ticks_s(self) -> float:
        return self._reg("Profile_Velocity") * RPM_UNIT / 60 * self.res

    def _position_law(self, mode: int) -> bool:
        return mode in (3, 4, 5)

    def _open_loop_drive(self, mode: int, sign: float, cap: float) -> Drive | None:
        r = self.rating
        if mode == 0:
            return Drive(tau_ff_nm=sign * self._reg("Goal_Current") * r.current_unit_a * r.kt_nm_a, tau_max_nm=cap)
        if mode == 16:
            return Drive(tau_ff_nm=sign * r.stall_torque_nm * self._reg("Goal_PWM") / PWM_FULL, tau_max_nm=cap)
        return None

    def _on_latched(self) -> None:
        self.servo.set_reg("Torque_Enable", 0)  # the overload shuts the torque off
        self.servo.set_reg("Hardware_Error_Status", self._reg("Hardware_Error_Status") | OVERLOAD_BIT)

    def write_error(self, addr: int, data: bytes) -> int:
        """The status error of a refused write (0: accepted).

        Torque on while a hardware error stands (Access error, until a REBOOT); a current or current-based
        position ``Operating_Mode`` on a model without current sensing (Data Range error).
        """
        table = self.servo.table
        torque_addr, mode_addr = table["Torque_Enable"][0], table["Operating_Mode"][0]
        if addr <= torque_addr < addr + len(data) and self.torque_enable_refused(data[torque_addr - addr]):
            return 0x80 | 7
        current_mode = addr <= mode_addr < addr + len(data) and data[mode_addr - addr] in (0, 5)
        if current_mode and not self.rating.current_limit:
            return 4
        return 0

    def torque_enable_refused(self, value: int) -> bool:
        """Torque on is refused while a hardware error stands (until a REBOOT)."""
        return bool(value) and bool(self._reg("Hardware_Error_Status"))

    def error_byte(self) -> int:
        """The alert bit 0x80 while a hardware error stands."""
        return 0x80 if self._reg("Hardware_Error_Status") else 0

    def _refresh_vendor(self, tau_nm: float, v_ticks_s: float) -> bool | None:
        del v_ticks_s
        r, p = self.rating, self.plant
        v_units = round(p.v_rad_s * 60 / math.tau / RPM_UNIT * self._sign)
        cur = round(tau_nm / r.kt_nm_a / r.current_unit_a)
        self._raw("Present_Current", encode_twos_complement(max(-32768, min(32767, cur)), 2))
        self._raw("Present_Velocity", encode_twos_complement(v_units, 4))
        temp_c, volt_v = self.thermal.update(self.clock.now(), tau_nm / r.kt_nm_a)
        self._raw("Present_Temperature", min(255, round(temp_c)))
        self._raw("Present_Input_Voltage", round(volt_v * 10))
        return abs(v_units) > self._reg("Moving_Threshold") or self.ramp_ticks_s != 0.0


DYNAMIXEL_SIM = SimServoKind(
    vendor="dynamixel",
    models=DYNAMIXEL_MODELS,
    power_on=(("Operating_Mode", 3), ("Baud_Rate", 3), ("Firmware_Version", 52)),  # 1 Mbit/s, as LeRobot's setup
    baud_rates={
        0: 9_600,
        1: 57_600,
        2: 115_200,
        3: 1_000_000,
        4: 2_000_000,
        5: 3_000_000,
        6: 4_000_000,
        7: 4_500_000,
    },
    factory_baud=1,  # 57600 bit/s as shipped
    twos_complement=(
        "Homing_Offset",
        "Present_Position",
        "Goal_Position",
        "Max_Position_Limit",
        "Min_Position_Limit",
        "Bus_Watchdog",
    ),
    clamps_goal=False,
    value_ranges={  # e-Manual (X series): a write outside is refused with a Data Range error
        "Min_Position_Limit": (0, 4095),
        "Max_Position_Limit": (0, 4095),
        "Homing_Offset": (-1_044_479, 1_044_479),
    },
    range_error=4,
    single_turn_mode=3,
    address_bytes=2,
    parse=parse_dynamixel,
    status=dynamixel_status,
    ping_reports_model=True,
    reboot=True,
    unknown_instruction_error=2,
    eeprom_locked_by_torque=True,
    firmware=DynamixelFirmware,
    status_level="Status_Return_Level",
    reply_levels={0x01: 0, 0x02: 1},  # 0: PING only; 1: PING and READ; 2: all (the e-Manual)
    full_reply_level=2,
)
"""How simulated Dynamixel X servos behave on the bus and in their firmware."""
