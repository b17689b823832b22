"""The firmware of a simulated servo with physics: what every vendor shares (frames, ramp, integration, hooks).

Each vendor's control law, protection and status bits are a subclass in its home
(:class:`robocal.backends.feetech.sim.FeetechFirmware`, :class:`robocal.backends.dynamixel.sim.DynamixelFirmware`),
named by the vendor's :class:`~robocal.backends.sim.servo_kind.SimServoKind` (``firmware``).

A :class:`ServoFirmware` joins one :class:`~robocal.backends.sim.servo.SimServo` (its control table) to a
:class:`~robocal.backends.sim.physics.JointPlant` on a :class:`~robocal.backends.sim.physics.SimClock`. The
simulated bus calls :meth:`ServoFirmware.sync` before it handles each packet (after advancing the clock by the bus
latency), :meth:`ServoFirmware.after_write` after a register write and :meth:`ServoFirmware.refresh` before a
read. Plant radians map to the servo's actual ticks as ``ticks = zero_ticks + q·resolution/2π``.

The control laws (joint torque τ from the setpoint error in ticks and the velocity) are in the vendors' modules.

Torque on (``Torque_Enable`` 0 → 1) sets ``Goal_Position`` to the present position, so the servo holds where it
is. Ratings (:data:`RATINGS`) are datasheet stall torques and currents. The gains' scaling, the protection
defaults of Dynamixel and the Goal_Position update at torque-on are assumptions (docs/sim.md lists them).
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

from ..servo_ratings import RATINGS, MotorRating
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

    LATCH_SWITCHES_TORQUE_OFF = False
    """An overload latch switches the torque off and keeps it off until a REBOOT (Dynamixel)."""
    TORQUE_OFF_CLEARS_LATCH = False
    """Switching the torque off clears the overload latch (Feetech)."""

    def __init__(self, servo: SimServo, plant: JointPlant, clock: SimClock, *, zero_ticks: float) -> None:
        self.servo = servo
        self.plant = plant
        self.clock = clock
        self.zero_ticks = float(zero_ticks)
        self.rating = RATINGS[servo.model]
        self.res = servo.resolution
        self.setpoint_ticks = servo.actual_ticks
        self.ramp_ticks_s = 0.0
        self.scenario_overload = plant.overload
        """A scenario's overload latch (from :func:`~.scenarios.make_plant`) replaces the firmware's own rule."""
        self._law_key: tuple[bytes, float] | None = None
        self._law: tuple[bool, bool, float, float, OverloadLatch | None] = (False, False, 0.0, 0.0, None)
        self._drive_key: tuple[bytes, float, float] | None = None
        self._drive = Drive()
        self._held: tuple[bytes, float, float] | None = None  # (registers, shaft, setpoint) of a joint at rest
        self._power_on_registers()
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

    # ----------------------------------------------------------------------------------------- the law
    # ------------------------------------------------------------------------------- the vendor's law
    def _power_on_registers(self) -> None:
        """Set the registers the firmware's law reads to their power-on values (the vendor's defaults)."""
        raise NotImplementedError

    @property
    def _sign(self) -> float:
        """+1, or −1 where the vendor inverts the reading in the motor (Dynamixel ``Drive_Mode`` bit 0)."""
        return 1.0

    def _position_gains(self) -> tuple[float, float]:
        """(kp N·m/rad, kd N·m·s/rad) of the position loop."""
        raise NotImplementedError

    def _cap(self) -> float:
        """The torque the firmware may output now, N·m."""
        raise NotImplementedError

    def _overload(self) -> OverloadLatch:
        """The overload rule now: a scenario's latch, else the vendor's own (:meth:`_vendor_overload`)."""
        if self.scenario_overload is not None:
            return self.scenario_overload
        return self._vendor_overload()

    def _vendor_overload(self) -> OverloadLatch:
        """The vendor's overload rule from its registers."""
        raise NotImplementedError

    def _velocity_ref_rad_s(self) -> float:
        """The velocity mode's goal, rad/s (before the sign)."""
        raise NotImplementedError

    def _ramp_speed_ticks_s(self) -> float:
        """Speed of the position setpoint, ticks/s (0: jumps)."""
        raise NotImplementedError

    def _position_law(self, mode: int) -> bool:
        """``Operating_Mode`` ``mode`` runs the position law."""
        raise NotImplementedError

    def _open_loop_drive(self, mode: int, sign: float, cap: float) -> Drive | None:
        """The drive of a mode without a position or velocity loop (current, PWM), or None."""
        del mode, sign, cap
        return None

    def _refresh_vendor(self, tau_nm: float, v_ticks_s: float) -> bool | None:
        """Write the vendor's Present_* registers and fault bits; returns ``Moving`` (None: the default rule)."""
        raise NotImplementedError

    def _on_latched(self) -> None:
        """The overload latched while the torque is on (only where :attr:`LATCH_SWITCHES_TORQUE_OFF`)."""

    def drive(self) -> Drive:
        """The torque law now, in the plant frame (limp with torque off)."""
        if not self.torque_on:
            return Drive()
        mode, sign, cap = self._reg("Operating_Mode"), self._sign, self._cap()
        r = self.rating
        open_loop = self._open_loop_drive(mode, sign, cap)
        if open_loop is not None:
            return open_loop
        if mode == 1:
            kv = r.stall_torque_nm / (200 * math.tau / self.res)  # saturates 200 ticks/s off the goal speed
            return Drive(kd_nms_rad=kv, v_ref_rad_s=sign * self._velocity_ref_rad_s(), tau_max_nm=cap)
        kp, kd = self._position_gains()
        v_ref = self.ramp_ticks_s * math.tau / self.res
        return Drive(kp, kd, self.rad(self.setpoint_ticks), v_ref, 0.0, cap)

    # ------------------------------------------------------------------------------------------- hooks
    def _registers_law(self) -> tuple[bool, bool, float, float, OverloadLatch | None]:
        """(torque on, position law, goal in actual ticks, ramp speed, overload rule) from the registers.

        A pure function of the registers and the shaft's turn (for the goal), so it is kept until they change:
        the firmware of a servo that only holds its pose costs almost nothing per packet.
        """
        key = (bytes(self.servo.regs), self.servo.actual_ticks)
        if key != self._law_key:
            mode = self._reg("Operating_Mode")
            position_law = self._position_law(mode)
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
            if self.LATCH_SWITCHES_TORQUE_OFF and plant.latched and self.torque_on:
                self._on_latched()
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
            and not (self.LATCH_SWITCHES_TORQUE_OFF and plant.latched and on)
            and plant.hold_until(plant.t_s, self._current_drive())
        ):
            self._held = (bytes(self.servo.regs), self.servo.actual_ticks, self.setpoint_ticks)

    def after_write(self, addr: int, size: int, torque_was_on: bool) -> None:
        """A register write was applied: torque-on holds the present position; torque-off may clear the latch."""
        on = self.torque_on
        if on and not torque_was_on:
            self.setpoint_ticks = self.servo.actual_ticks
            self.servo.set_reg("Goal_Position", self.servo.present_ticks())
        if not on and torque_was_on and self.TORQUE_OFF_CLEARS_LATCH:
            self.plant.clear_overload()

    def write_error(self, addr: int, data: bytes) -> int:
        """The status error of a write the firmware refuses (0: accepted)."""
        del addr, data
        return 0

    def torque_enable_refused(self, value: int) -> bool:
        """Whether the firmware refuses switching the torque on now."""
        del value
        return False

    def reboot(self) -> None:
        """Dynamixel REBOOT: clears the hardware error; the torque stays off."""
        self.servo.set_reg("Hardware_Error_Status", 0)
        self.servo.set_reg("Torque_Enable", 0)
        self.plant.clear_overload()

    def error_byte(self) -> int:
        """The error field of a status packet."""
        raise NotImplementedError

    def answers(self) -> bool:
        """False while the plant's replies are lost."""
        return self.plant.answers()

    def refresh(self) -> None:
        """Write the Present_* registers, Moving and the fault bits (before a read)."""
        s, p = self.servo, self.plant
        tau = p.tau_motor_nm * self._sign
        v_ticks = p.v_rad_s * self.res / math.tau * self._sign
        moving = abs(v_ticks) > 20 or self.ramp_ticks_s != 0.0
        vendor_moving = self._refresh_vendor(tau, v_ticks)
        if vendor_moving is not None:
            moving = vendor_moving
        s.set_reg("Moving", int(moving))

    def _raw(self, name: str, raw: int) -> None:
        addr, size = self.servo.table[name]
        self.servo.regs[addr : addr + size] = self.servo._pack(raw, size)
