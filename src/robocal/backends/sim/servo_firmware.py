"""The firmware of a simulated Feetech or Dynamixel servo with physics: control law, saturation, protection.

A :class:`ServoFirmware` joins one :class:`~robocal.backends.sim.servo.SimServo` (its control table) to a
:class:`~robocal.backends.sim.physics.JointPlant` on a :class:`~robocal.backends.sim.physics.SimClock`. The
simulated bus calls :meth:`ServoFirmware.sync` before it handles each packet (after advancing the clock by the bus
latency), :meth:`ServoFirmware.after_write` after a register write and :meth:`ServoFirmware.refresh` before a
read. Plant radians map to the servo's actual ticks as ``ticks = zero_ticks + q·resolution/2π``.

Control laws (joint torque τ; ``e`` the setpoint error in ticks, ``ω`` the velocity):

* Feetech STS/SCS, ``Operating_Mode`` 0 (position): ``τ = clip(P/1024·τ_stall·e − D·0.005·τ_stall·ω,
  ±τ_stall·Torque_Limit/1000)`` with ``P_Coefficient``, ``D_Coefficient``; the setpoint moves toward
  ``Goal_Position`` at ``Goal_Velocity`` ticks/s (0: at once). ``Operating_Mode`` 1 (velocity): a velocity loop to
  the signed ``Goal_Velocity`` (ticks/s), same torque cap. Overload protection: ``|τ| ≥ τ_stall·Overload_Torque %``
  for ``Protection_Time``·10 ms sets ``Status`` bit 5 and limits the torque to ``Protective_Torque %`` until the
  torque is switched off. ``Present_Load`` is τ/τ_stall in 0.1 % (sign bit 10), ``Present_Current`` in 6.5 mA,
  ``Present_Velocity`` in ticks/s, ``Moving`` while |ω| > 20 ticks/s or the setpoint is travelling.
* Dynamixel X: ``Operating_Mode`` 5 (current-based position): ``τ = clip(kt·i_unit·(P/128·e − D/16·ω_ms),
  ±kt·i_unit·min(|Goal_Current|, Current_Limit))`` with ``Position_P_Gain``, ``Position_D_Gain`` (``ω_ms`` in
  ticks/ms), setpoint ramped at ``Profile_Velocity`` (0.229 rev/min; 0: at once); modes 3/4 the same law capped
  at ``τ_stall·min(PWM_Limit, |Goal_PWM|)/885`` (``Goal_PWM`` also limits mode 5); mode 1 velocity, mode 0 current (``Goal_Current``), mode 16 PWM.
  ``Present_Current`` in the model's current unit, ``Present_Velocity`` in 0.229 rev/min, ``Moving`` above
  ``Moving_Threshold``. Overload: ≥ 95 % of the mode's maximum output for 1 s sets ``Hardware_Error_Status``
  bit 5, switches the torque off and keeps it off (the alert bit 0x80 in every status packet) until a REBOOT.

Torque on (``Torque_Enable`` 0 → 1) sets ``Goal_Position`` to the present position, so the servo holds where it
is. Ratings (:data:`RATINGS`) are datasheet stall torques and currents. The gains' scaling, the protection
defaults of Dynamixel and the Goal_Position update at torque-on are assumptions (docs/sim.md lists them).
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

from ...core.lerobot import encode_sign_magnitude, encode_twos_complement
from ..servo_ratings import OVERLOAD_BIT, PWM_FULL, RATINGS, RPM_UNIT, MotorRating
from .physics import Drive, JointPlant, OverloadLatch, SimClock

if TYPE_CHECKING:
    from .servo import SimServo

__all__ = ["RATINGS", "MotorRating", "ServoFirmware"]


_CHUNK_S = 0.005  # the setpoint ramp is updated at least every 5 ms of simulated time


class ServoFirmware:
    """The firmware of one simulated servo driving a plant (see the module docstring).

    Args:
        servo: The servo (its registers are the firmware's state).
        plant: The joint.
        clock: Simulated time.
        zero_ticks: Actual ticks at plant position 0.
    """

    def __init__(self, servo: SimServo, plant: JointPlant, clock: SimClock, *, zero_ticks: float) -> None:
        self.servo = servo
        self.plant = plant
        self.clock = clock
        self.zero_ticks = float(zero_ticks)
        self.rating = RATINGS[servo.model]
        self.res = servo.resolution
        self.setpoint_ticks = servo.actual_ticks
        self.ramp_ticks_s = 0.0
        self.dxl = servo.kind.x_series_law
        """Runs the Dynamixel X control law (else the Feetech STS one); the vendor's simulator adapter says."""
        self.scenario_overload = plant.overload
        """A scenario's overload latch (from :func:`~.scenarios.make_plant`) replaces the firmware's own rule."""
        self._law_key: tuple[bytes, float] | None = None
        self._law: tuple[bool, bool, float, float, OverloadLatch | None] = (False, False, 0.0, 0.0, None)
        self._drive_key: tuple[bytes, float, float] | None = None
        self._drive = Drive()
        self._held: tuple[bytes, float, float] | None = None  # (registers, shaft, setpoint) of a joint at rest
        s = servo
        if self.dxl:
            s.set_reg("Current_Limit", self.rating.current_limit)
            s.set_reg("Goal_Current", self.rating.current_limit)
            s.set_reg("PWM_Limit", PWM_FULL)
            s.set_reg("Goal_PWM", PWM_FULL)  # RAM: PWM_Limit at power-on
            s.set_reg("Position_P_Gain", 800)
            s.set_reg("Moving_Threshold", 10)
            s.set_reg("Shutdown", 0x34)
        elif "Torque_Limit" in s.table:
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
        plant.set_state(self.rad(servo.actual_ticks))

    # ------------------------------------------------------------------------------------------ frames
    def rad(self, actual_ticks: float) -> float:
        """Actual ticks → plant radians."""
        return (actual_ticks - self.zero_ticks) * math.tau / self.res

    def ticks(self, q_rad: float) -> float:
        """Plant radians → actual ticks."""
        return self.zero_ticks + q_rad * self.res / math.tau

    def _reg(self, name: str, default: int = 0) -> int:
        return self.servo.get_reg(name) if name in self.servo.table else default

    @property
    def torque_on(self) -> bool:
        """``Torque_Enable`` is set."""
        return bool(self._reg("Torque_Enable"))

    @property
    def _sign(self) -> float:
        return -1.0 if self.dxl and self._reg("Drive_Mode") & 1 else 1.0

    # ----------------------------------------------------------------------------------------- the law
    def _position_gains(self) -> tuple[float, float]:
        """(kp N·m/rad, kd N·m·s/rad) of the position loop."""
        per_rad = self.res / math.tau
        r = self.rating
        if self.dxl:
            amp = r.current_unit_a * r.kt_nm_a
            kp = self._reg("Position_P_Gain") / 128 * amp * per_rad
            kd = self._reg("Position_D_Gain") / 16 * amp * per_rad * 0.001
            return kp, kd
        p, d = self._reg("P_Coefficient", 32), self._reg("D_Coefficient", 32)
        return p / 1024 * r.stall_torque_nm * per_rad, d * 0.005 * r.stall_torque_nm

    def _cap(self) -> float:
        r = self.rating
        if not self.dxl:
            return r.stall_torque_nm * min(1000, self._reg("Torque_Limit", 1000)) / 1000
        pwm = min(PWM_FULL, self._reg("PWM_Limit"))
        if self._reg("Operating_Mode") in (3, 4, 5):  # Goal_PWM limits the output of the position modes
            pwm = min(pwm, abs(self._reg("Goal_PWM")))
        pwm_cap = r.stall_torque_nm * pwm / PWM_FULL
        if self._reg("Operating_Mode") in (0, 5):
            amps = min(abs(self._reg("Goal_Current")), self._reg("Current_Limit")) * r.current_unit_a
            return min(pwm_cap, amps * r.kt_nm_a)
        return pwm_cap

    def _overload(self) -> OverloadLatch:
        if self.scenario_overload is not None:
            return self.scenario_overload
        r = self.rating
        if self.dxl:
            return OverloadLatch(
                0.95 * r.stall_torque_nm * min(1.0, self._reg("PWM_Limit") / PWM_FULL), 1.0, 0.0
            )
        return OverloadLatch(
            r.stall_torque_nm * self._reg("Overload_Torque", 80) / 100,
            self._reg("Protection_Time", 200) * 0.01,
            r.stall_torque_nm * self._reg("Protective_Torque", 20) / 100,
        )

    def _velocity_ref_rad_s(self) -> float:
        if self.dxl:
            return self._reg("Goal_Velocity") * RPM_UNIT / 60 * math.tau
        name = "Goal_Velocity" if "Goal_Velocity" in self.servo.table else "Goal_Speed"
        return self._reg(name) * math.tau / self.res

    def drive(self) -> Drive:
        """The torque law now, in the plant frame (limp with torque off)."""
        if not self.torque_on:
            return Drive()
        mode, sign, cap = self._reg("Operating_Mode"), self._sign, self._cap()
        r = self.rating
        if self.dxl and mode == 0:
            return Drive(
                tau_ff_nm=sign * self._reg("Goal_Current") * r.current_unit_a * r.kt_nm_a, tau_max_nm=cap
            )
        if self.dxl and mode == 16:
            return Drive(
                tau_ff_nm=sign * r.stall_torque_nm * self._reg("Goal_PWM") / PWM_FULL, tau_max_nm=cap
            )
        if mode == 1:
            kv = r.stall_torque_nm / (200 * math.tau / self.res)  # saturates 200 ticks/s off the goal speed
            return Drive(kd_nms_rad=kv, v_ref_rad_s=sign * self._velocity_ref_rad_s(), tau_max_nm=cap)
        kp, kd = self._position_gains()
        v_ref = self.ramp_ticks_s * math.tau / self.res
        return Drive(kp, kd, self.rad(self.setpoint_ticks), v_ref, 0.0, cap)

    def _ramp_speed_ticks_s(self) -> float:
        """Speed of the setpoint (0: jumps)."""
        if self.dxl:
            return self._reg("Profile_Velocity") * RPM_UNIT / 60 * self.res
        name = "Goal_Velocity" if "Goal_Velocity" in self.servo.table else "Goal_Speed"
        return float(abs(self._reg(name)))

    # ------------------------------------------------------------------------------------------- hooks
    def _registers_law(self) -> tuple[bool, bool, float, float, OverloadLatch | None]:
        """(torque on, position law, goal in actual ticks, ramp speed, overload rule) from the registers.

        A pure function of the registers and the shaft's turn (for the goal), so it is kept until they change:
        the firmware of a servo that only holds its pose costs almost nothing per packet.
        """
        key = (bytes(self.servo.regs), self.servo.actual_ticks)
        if key != self._law_key:
            mode = self._reg("Operating_Mode")
            position_law = mode in (3, 4, 5) if self.dxl else mode == 0
            on = self.torque_on
            goal = speed = 0.0
            if on and position_law:
                goal = self.servo.goal_to_actual(self.servo.get_reg("Goal_Position"))
                speed = self._ramp_speed_ticks_s()
            self._law_key, self._law = key, (on, position_law, goal, speed, self._overload())
        return self._law

    def _current_drive(self) -> Drive:
        """:meth:`drive`, kept while the registers, the setpoint and its ramp stay the same."""
        key = (bytes(self.servo.regs), self.setpoint_ticks, self.ramp_ticks_s)
        if key != self._drive_key:
            self._drive_key, self._drive = key, self.drive()
        return self._drive

    def sync(self, until_s: float | None = None) -> None:
        """Integrate the plant to the clock (or to ``until_s`` before it), moving the setpoint along its ramp.

        A joint that rested at the end of the last sync, with the same registers and setpoint (nothing written to
        it, no ramp, no encoder noise), only has its time moved on: what the loop below would do for it.
        """
        plant, now = self.plant, self.clock.now() if until_s is None else min(until_s, self.clock.now())
        plant.overload = self._registers_law()[4]
        held = (bytes(self.servo.regs), self.servo.actual_ticks, self.setpoint_ticks)
        if held == self._held and plant.hold_until(now, self._current_drive()):
            return
        self._held = None
        while plant.t_s < now - 1e-12:
            t_next = min(now, plant.t_s + _CHUNK_S)
            self.ramp_ticks_s = 0.0
            on, position_law, goal, speed, _ = self._registers_law()
            if on and position_law:
                err = goal - self.setpoint_ticks
                if speed <= 0 or abs(err) <= speed * (t_next - plant.t_s):
                    self.setpoint_ticks = goal
                else:
                    self.setpoint_ticks += math.copysign(speed * (t_next - plant.t_s), err)
                    self.ramp_ticks_s = math.copysign(speed, err)
            plant.run_until(t_next, self._current_drive())
            if plant.t_s < t_next - 1e-12:  # the plant's step is coarser than what is left
                break
            if self.dxl and plant.latched and self.torque_on:
                self.servo.set_reg("Torque_Enable", 0)  # the overload shuts the torque off
                self.servo.set_reg("Hardware_Error_Status", self._reg("Hardware_Error_Status") | OVERLOAD_BIT)
        self.servo.actual_ticks = self.ticks(plant.read().q_rad)
        self._note_held(now)

    def _note_held(self, now: float) -> None:
        """Remember a joint that rests at its setpoint with nothing left to do (for the next :meth:`sync`)."""
        plant = self.plant
        on, position_law, goal, _, _ = self._registers_law()
        if (
            plant.params.noise_rad == 0.0
            and self.ramp_ticks_s == 0.0
            and plant.t_s >= now - 1e-12
            and not (on and position_law and self.setpoint_ticks != goal)
            and not (self.dxl and plant.latched and on)
            and plant.hold_until(plant.t_s, self._current_drive())
        ):
            self._held = (bytes(self.servo.regs), self.servo.actual_ticks, self.setpoint_ticks)

    def after_write(self, addr: int, size: int, torque_was_on: bool) -> None:
        """A register write was applied: torque-on holds the present position; torque-off clears Feetech's latch."""
        on = self.torque_on
        if on and not torque_was_on:
            self.setpoint_ticks = self.servo.actual_ticks
            self.servo.set_reg("Goal_Position", self.servo.present_ticks())
        if not on and torque_was_on and not self.dxl:
            self.plant.clear_overload()

    def write_error(self, addr: int, data: bytes) -> int:
        """The status error of a write the firmware refuses (0: accepted).

        Dynamixel: torque on while a hardware error stands (Access error, until a REBOOT); a current or
        current-based position ``Operating_Mode`` on a model without current sensing (Data Range error).
        """
        if not self.dxl:
            return 0
        table = self.servo.table
        torque_addr, mode_addr = table["Torque_Enable"][0], table["Operating_Mode"][0]
        if addr <= torque_addr < addr + len(data) and self.torque_enable_refused(data[torque_addr - addr]):
            return 0x80 | 7
        current_mode = addr <= mode_addr < addr + len(data) and data[mode_addr - addr] in (0, 5)
        if current_mode and not self.rating.current_limit:
            return 4
        return 0

    def torque_enable_refused(self, value: int) -> bool:
        """Dynamixel refuses torque on while a hardware error stands (until a REBOOT)."""
        return self.dxl and bool(value) and bool(self._reg("Hardware_Error_Status"))

    def reboot(self) -> None:
        """Dynamixel REBOOT: clears the hardware error; the torque stays off."""
        self.servo.set_reg("Hardware_Error_Status", 0)
        self.servo.set_reg("Torque_Enable", 0)
        self.plant.clear_overload()

    def error_byte(self) -> int:
        """The error field of a status packet (Feetech: the ``Status`` bits; Dynamixel: alert bit 0x80)."""
        if self.dxl:
            return 0x80 if self._reg("Hardware_Error_Status") else 0
        return OVERLOAD_BIT if self.plant.latched else 0

    def answers(self) -> bool:
        """False while the plant's replies are lost."""
        return self.plant.answers()

    def refresh(self) -> None:
        """Write the Present_* registers, Moving and the fault bits (before a read)."""
        s, p, r = self.servo, self.plant, self.rating
        tau = p.tau_motor_nm * self._sign
        v_ticks = p.v_rad_s * self.res / math.tau * self._sign
        moving = abs(v_ticks) > 20 or self.ramp_ticks_s != 0.0
        if self.dxl:
            v_units = round(p.v_rad_s * 60 / math.tau / RPM_UNIT * self._sign)
            cur = round(tau / r.kt_nm_a / r.current_unit_a)
            self._raw("Present_Current", encode_twos_complement(max(-32768, min(32767, cur)), 2))
            self._raw("Present_Velocity", encode_twos_complement(v_units, 4))
            moving = abs(v_units) > self._reg("Moving_Threshold") or self.ramp_ticks_s != 0.0
        else:
            if "Present_Load" in s.table:
                load = max(-1000, min(1000, round(tau / r.stall_torque_nm * 1000)))
                self._raw("Present_Load", encode_sign_magnitude(load, 10) if not s.big_endian else abs(load))
            if "Present_Current" in s.table:
                self._raw("Present_Current", min(0x7FFF, round(abs(tau) / r.kt_nm_a / r.current_unit_a)))
            name = "Present_Velocity" if "Present_Velocity" in s.table else "Present_Speed"
            v = max(-32767, min(32767, round(v_ticks)))
            self._raw(name, encode_sign_magnitude(v, 15) if not s.big_endian else v & 0xFFFF)
            if "Status" in s.table:
                status = self._reg("Status") & ~OVERLOAD_BIT
                s.set_reg("Status", status | (OVERLOAD_BIT if p.latched else 0))
        s.set_reg("Moving", int(moving))

    def _raw(self, name: str, raw: int) -> None:
        addr, size = self.servo.table[name]
        self.servo.regs[addr : addr + size] = self.servo._pack(raw, size)
