"""Feetech and Dynamixel servos as joint drivers of the automatic hard-stop calibration (real registers).

The Feetech and Dynamixel equivalents of :class:`~robocal.workflows.autocal.robstride_driver.RobstrideJointDriver`:
:class:`FeetechJointDriver` and :class:`DynamixelJointDriver` carry out the
:class:`~robocal.core.stop_search.StopSearch` commands through the vendor SDK buses
(:class:`~robocal.backends.feetech.FeetechBus`, :class:`~robocal.backends.dynamixel.DynamixelBus`), so the same
code drives a real arm and the simulated firmware on a pseudo-terminal.

* **Feetech STS** (``Operating_Mode`` 0, position servo): every control period the position goal steps along the
  search ramp (``Goal_Position``, ``Goal_Velocity`` 0 = follow at once); the torque cap is ``Torque_Limit``
  (0.1 % of the motor's full torque: ``1000·cap/stall``); readings are ``Present_Position``,
  ``Present_Velocity`` (ticks/s), ``Present_Load`` (0.1 % of full torque, signed) and ``Status`` (bit 5 overload,
  bit 3 over-current: suspect; bits 0–2 voltage, sensor, temperature: fatal). A clear (``reread``) is torque
  off (that clears the overload latch), a position read, the goal set to it, torque on.
* **Dynamixel X** (``Operating_Mode`` 5, current-based position, where the model senses current): the goal steps
  the same way (``Profile_Velocity`` 0); the cap is ``Goal_Current`` (``cap/stall·stall current``); readings are
  ``Present_Position``, ``Present_Velocity`` (0.229 rev/min), ``Present_Current`` and ``Hardware_Error_Status``
  (bit 5 overload: suspect, the firmware has switched the torque off; any other bit: fatal). A clear is torque
  off (a motor pressed into a stop may lose its replies until it stops pushing), then, if a hardware error
  stands, a REBOOT (the only way out of it) and the RAM limits written again; goal = present, torque on. Models
  without current sensing (XL430) run in extended position mode 4 with ``Goal_PWM`` as the cap.

Joint frame: ``s = ticks·2π/resolution`` of an unwrapped tick count (continuous across the encoder seam), radians,
positive where Present_Position grows (Dynamixel with ``Drive_Mode`` as the arm's profile sets it). Torques are in
N·m; a register's full scale is the model's stall torque from :mod:`robocal.core.motor_models`, and no torque
limit written is above the model's hard ceiling (:data:`~robocal.core.motor_models.HARD_MAX_TORQUE_FRACTION` of
its rating), whatever the caller asks. Writes that move the motor during the search are
SYNC_WRITEs (no status packet: a latched servo's error byte cannot turn them into exceptions); reads are
SYNC_READs of one motor (one block per reading where the registers are adjacent). :meth:`limp` is a SYNC_WRITE of ``Torque_Enable`` 0 and never raises.

A Feetech position goal must stay inside one turn (0..res−1, the firmware does not wrap): when the joint comes
within :data:`SEAM_MARGIN_TICKS` of the seam the driver re-homes it (torque off, ``Homing_Offset`` so the
present position reads mid-turn, goal = present, torque on), so a search may travel almost a whole turn. The
limits (``Min/Max_Position_Limit`` 0..res−1), modes and offsets the search needs are set by the caller
(:mod:`robocal.workflows.lerobot.auto`), which snapshots and restores them.
"""

from __future__ import annotations

import math
from contextlib import suppress
from typing import Any

from ...backends.servo_ratings import OVERLOAD_BIT, PWM_FULL, RATINGS, RPM_UNIT
from ...core.lerobot.homing import half_turn_homing_offset
from ...core.motor_models import MotorModel, find_motor_model, motor_key
from ...core.stop_search import Command, StopSample
from ...errors import CalibTimeoutError, DeviceError, UsageError
from .model import Clock

__all__ = [
    "DXL_FATAL_BITS",
    "FEETECH_FATAL_BITS",
    "FEETECH_SUSPECT_BITS",
    "SEAM_MARGIN_TICKS",
    "SERVO_DRIVERS",
    "DynamixelJointDriver",
    "FeetechJointDriver",
    "dynamixel_current_mode",
    "mid_turn_offset",
    "servo_driver_class",
]

SEAM_MARGIN_TICKS = 512
"""A Feetech joint this close (ticks) to the 0/res−1 seam is re-homed to mid-turn before the next goal."""
FEETECH_SUSPECT_BITS = OVERLOAD_BIT | 0x08
"""Feetech ``Status`` bits 5 (overload) and 3 (over-current): suspect evidence, cleared by torque off."""
FEETECH_FATAL_BITS = 0x01 | 0x02 | 0x04
"""Feetech ``Status`` bits 0 (voltage), 1 (magnetic sensor), 2 (temperature): the run ends."""
DXL_FATAL_BITS = 0x01 | 0x04 | 0x08 | 0x10
"""Dynamixel ``Hardware_Error_Status`` bits 0 (voltage), 2 (overheating), 3 (encoder), 4 (electrical shock)."""
_FEETECH_READ = ("Present_Position", "Present_Velocity", "Present_Load", "Status")  # addresses 56..65
_DXL_READ = ("Present_Current", "Present_Velocity", "Present_Position")  # addresses 126..135


def mid_turn_offset(actual_ticks: int, res: int) -> int:
    """The Feetech ``Homing_Offset`` that makes a joint at ``actual_ticks`` (0..res−1) read mid-turn.

    ``Present = (Actual − Homing_Offset) mod res``; the offset is kept inside the sign-magnitude register's
    ±(res/2 − 1), so the seam is (almost) half a turn away.
    """
    return half_turn_homing_offset(actual_ticks, vendor="feetech", resolution=res)  # the one homing rule


def dynamixel_current_mode(model: str) -> bool:
    """Whether a Dynamixel model senses current (current-based position mode 5 with ``Goal_Current``)."""
    rating = RATINGS.get(model)
    return rating is not None and rating.current_limit > 0


def _motor_model(joint: str, bus_model: str, motor: str | None) -> MotorModel:
    """The model table entry of a servo: ``motor`` (a variant such as ``sts3215-12v``) or the bus model.

    Raises:
        UsageError: The model is unknown, or ``motor`` is not a variant of the bus model.
    """
    found = find_motor_model(motor or bus_model)
    if found is None:
        raise UsageError(f"joint {joint}: motor model {motor or bus_model!r} has no rating in robocal's model table")
    if motor_key(found.bus_model) != motor_key(bus_model):
        raise UsageError(f"joint {joint}: motor {found.name} answers as {found.bus_model!r}, the bus has {bus_model!r}")
    return found


class _ServoJointDriver:
    """What the Feetech and Dynamixel drivers share: the tick frame, the period, enable, the command loop.

    The constructor's arguments are described on each driver; ``homing_offset`` is the motor's ``Homing_Offset``
    register as the caller set it (Feetech unwraps Present with it and re-homing changes it; the Dynamixel search
    runs with it at 0).
    """

    def __init__(
        self,
        bus: Any,
        name: str,
        motor_id: int,
        *,
        rated_nm: float,
        cap_nm: float,
        clock: Clock,
        period_s: float = 0.01,
        homing_offset: int = 0,
        motor: str | None = None,
    ) -> None:
        if not (
            math.isfinite(rated_nm) and rated_nm > 0 and math.isfinite(cap_nm) and 0 < cap_nm <= rated_nm
        ):
            raise UsageError(
                f"joint {name}: torque cap {cap_nm!r} N·m must be in (0, rated {rated_nm!r} N·m]"
            )
        self.bus = bus
        self.name = name
        self.motor_id = int(motor_id)
        self.model = str(bus.motors[motor_id])
        self.motor_model = _motor_model(name, self.model, motor)
        self.full_nm = self.motor_model.stall_nm
        """The torque of ``Torque_Limit`` 1000 / the stall current / ``Goal_PWM`` 885 (the model's stall torque)."""
        self.ceiling_nm = self.motor_model.ceiling_nm
        """No torque limit written to the motor is above this (the hard ceiling of the model's rating)."""
        self.rated_nm = float(rated_nm)
        self.cap_nm = min(float(cap_nm), self.ceiling_nm)
        self.clock = clock
        self.period_s = period_s
        self.homing_offset = int(homing_offset)
        self.res = int(bus.resolution(motor_id))
        self.enabled = False
        self._ticks = math.nan  # unwrapped position (ticks) of the last good reading
        self._present = 0  # its Present_Position
        self._q = math.nan
        self._limit_nm = math.nan
        self._init_vendor()

    # -- frame ----------------------------------------------------------------------------------------
    def rad(self, ticks: float) -> float:
        """Unwrapped ticks → joint-frame radians."""
        return ticks * math.tau / self.res

    def ticks(self, s_rad: float) -> float:
        """Joint-frame radians → unwrapped ticks."""
        return s_rad * self.res / math.tau

    # -- vendor hooks ---------------------------------------------------------------------------------
    def _init_vendor(self) -> None:
        """The vendor's own checks and state, at the end of ``__init__``."""

    def _read_raw(self) -> tuple[int, float, float, int]:
        """(Present_Position, velocity rad/s, torque N·m, error bits); raises CalibTimeoutError on silence."""
        raise NotImplementedError

    def _unwrap(self, present: int) -> float:
        raise NotImplementedError

    def _flags(self, bits: int) -> bool:
        """Whether ``bits`` are suspect (overload); raises DeviceError for fatal bits."""
        raise NotImplementedError

    def _write_limit(self, limit_nm: float) -> None:
        raise NotImplementedError

    def _goal(self, target_ticks: float) -> int:
        """The Goal_Position for an unwrapped target (may re-home a Feetech joint first)."""
        raise NotImplementedError

    def _clear(self) -> None:
        """Clear a latch and hold the present position."""
        raise NotImplementedError

    # -- common ---------------------------------------------------------------------------------------
    def _sync(self, register: str, value: int) -> None:
        self.bus.sync_write(register, {self.motor_id: int(value)})

    def _read1(self, register: str) -> int:
        return int(self.bus.sync_read(register, [self.motor_id])[self.motor_id])

    def read(self) -> StopSample:
        """Read the joint without changing what the motor does (a lost reply gives ``ok=False``)."""
        try:
            present, v, tau, bits = self._read_raw()
        except CalibTimeoutError:
            return StopSample(self.clock.now(), math.nan, ok=False)
        suspect = self._flags(bits)
        self._ticks = self._unwrap(present)
        self._present = present
        self._q = self.rad(self._ticks)
        return StopSample(self.clock.now(), self._q, v, tau, True, suspect)

    def _set_limit(self, limit_nm: float) -> None:
        limit = min(max(limit_nm, 0.02 * self.cap_nm), self.cap_nm, self.ceiling_nm)  # never above the cap
        if limit != self._limit_nm:
            self._write_limit(limit)
            self._limit_nm = limit

    def _enable(self) -> None:
        if math.isnan(self._ticks):
            s = self.read()
            if not s.ok:
                raise CalibTimeoutError(f"joint {self.name}: no reply from motor {self.motor_id}")
        self._set_limit(self.cap_nm)
        self._sync("Goal_Position", self._present)  # torque on holds where the joint is
        self._sync("Torque_Enable", 1)
        self.enabled = True

    def execute(self, cmd: Command) -> StopSample:
        """Carry out ``cmd`` for one control period; the reading at its end."""
        t0 = self.clock.now()
        s = self.send(cmd)
        self.clock.sleep(max(0.0, self.period_s - (self.clock.now() - t0)))
        return s

    def send(self, cmd: Command) -> StopSample:
        """:meth:`execute` without waiting for the rest of the period: write ``cmd``, read the joint.

        For joints searched at the same time (:func:`robocal.workflows.autocal.group.run_lockstep`), which
        let one period pass for all of them.
        """
        if cmd.action == "limp":
            self.limp()
            return StopSample(self.clock.now(), self._q, ok=math.isfinite(self._q))
        try:
            if cmd.action == "reread":
                self._clear()
            else:
                if not self.enabled:
                    self._enable()
                self._set_limit(cmd.torque_limit_nm if cmd.torque_limit_nm > 0 else self.cap_nm)
                if math.isfinite(cmd.q_target_rad):
                    self._sync("Goal_Position", self._goal(self.ticks(cmd.q_target_rad)))
        except CalibTimeoutError:
            pass  # the reading below says so
        return self.read()

    def limp(self) -> None:
        """Torque off now (a SYNC_WRITE: no status packet to wait for); never raises."""
        with suppress(Exception):
            self._sync("Torque_Enable", 0)
        self.enabled = False


class FeetechJointDriver(_ServoJointDriver):
    """A Feetech STS servo in position mode driven through :class:`~robocal.backends.feetech.FeetechBus`.

    Args:
        bus: The arm's bus.
        name: Joint name.
        motor_id: Bus id.
        rated_nm: The rating the cap is a fraction of (N·m; the cap must not exceed it).
        cap_nm: Torque cap of the search (``Torque_Limit = 1000·cap/stall``, never exceeded, and never above the
            hard ceiling of the model's rating whatever is asked).
        clock: Time source; :meth:`execute` lets ``period_s`` pass per command.
        period_s: Control period.
        homing_offset: The motor's ``Homing_Offset`` now (the caller set it; re-homing changes it).
        motor: The motor model when it is a variant of the bus model (``sts3215-12v``); default the bus model.
            ``Torque_Limit`` and ``Present_Load`` 1000 are its stall torque (:mod:`robocal.core.motor_models`).
    """

    def _init_vendor(self) -> None:
        self.rehomes = 0
        """How many times the joint was re-homed away from the seam."""

    def _read_raw(self) -> tuple[int, float, float, int]:
        r = self.bus.sync_read_block(_FEETECH_READ, [self.motor_id])[self.motor_id]
        v = r["Present_Velocity"] * math.tau / self.res
        tau = r["Present_Load"] / 1000.0 * self.full_nm
        return r["Present_Position"], v, tau, r["Status"]

    def _flags(self, bits: int) -> bool:
        if bits & FEETECH_FATAL_BITS and self._read1("Status") & FEETECH_FATAL_BITS:  # read twice: confirmed
            raise DeviceError(
                f"joint {self.name}: motor {self.motor_id} Status {bits:#04x} (voltage, sensor or temperature)"
            )
        return bool(bits & FEETECH_SUSPECT_BITS)

    def _unwrap(self, present: int) -> float:
        actual = present + self.homing_offset  # Present = (Actual − Homing_Offset) mod res
        if math.isnan(self._ticks):
            return float(actual)
        half = self.res / 2
        delta = (actual - self._ticks + half) % self.res - half
        return self._ticks + delta

    def _write_limit(self, limit_nm: float) -> None:
        ceiling = math.floor(1000.0 * self.ceiling_nm / self.full_nm)
        self._sync("Torque_Limit", max(1, min(ceiling, round(1000.0 * limit_nm / self.full_nm))))

    def rehome(self) -> None:
        """Move the seam away: torque off, ``Homing_Offset`` so the joint reads mid-turn, goal there, torque on."""
        was_on = self.enabled
        self._sync("Torque_Enable", 0)
        self.enabled = False
        offset = mid_turn_offset(round(self._ticks) % self.res, self.res)
        try:
            self.bus.write("Homing_Offset", self.motor_id, offset)
        except CalibTimeoutError:
            offset = self._offset_on_servo()
        self.homing_offset = offset
        self.rehomes += 1
        s = self.read()
        if not s.ok:
            raise CalibTimeoutError(f"joint {self.name}: no reply after re-homing")
        if was_on:
            self._sync("Goal_Position", self._present)
            self._sync("Torque_Enable", 1)
            self.enabled = True

    def _offset_on_servo(self) -> int:
        """The ``Homing_Offset`` the servo holds after a write whose status packet was lost.

        The write may have been applied all the same (a motor silent while still pressed into a stop): every
        later reading depends on which offset the servo holds, so it is read back, never assumed.

        Raises:
            DeviceError: The servo does not answer the read-back either: its frame is unknown, the search
                cannot go on (a lost reply would otherwise turn into a jump of the joint's position).
        """
        try:
            return int(self.bus.read("Homing_Offset", self.motor_id))
        except CalibTimeoutError as exc:
            raise DeviceError(
                f"joint {self.name}: motor {self.motor_id} did not confirm its new Homing_Offset while re-homing "
                f"away from the encoder seam, and its frame is unknown ({exc})"
            ) from exc

    def _goal(self, target_ticks: float) -> int:
        if not SEAM_MARGIN_TICKS <= self._present <= self.res - 1 - SEAM_MARGIN_TICKS:
            self.rehome()
        goal = round(self._present + target_ticks - self._ticks)
        return max(0, min(self.res - 1, goal))

    def _clear(self) -> None:
        self._sync("Torque_Enable", 0)  # clears the overload latch
        self.enabled = False
        s = self.read()
        if s.ok:
            self._enable()


class DynamixelJointDriver(_ServoJointDriver):
    """A Dynamixel X servo in current-based position mode (5) through :class:`~robocal.backends.dynamixel.DynamixelBus`.

    Models without current sensing (XL430) are driven in extended position mode (4) with ``Goal_PWM`` as the
    cap (``885·cap/stall``); their ``Present_Current`` address is read as that model's load.

    Args:
        bus: The arm's bus.
        name: Joint name.
        motor_id: Bus id.
        rated_nm: The rating the cap is a fraction of (N·m).
        cap_nm: Torque cap (``Goal_Current = cap/stall torque·stall current``, never above the model's ceiling).
        clock: Time source.
        period_s: Control period.
    """

    def _init_vendor(self) -> None:
        if self.model not in RATINGS:
            raise UsageError(f"joint {self.name}: no rating for Dynamixel model {self.model!r}")
        self.rating = RATINGS[self.model]
        self.current_mode = dynamixel_current_mode(self.model)
        self.reboots = 0
        """How many REBOOTs cleared a hardware error."""
        self.ram: dict[str, int] = {}
        """RAM registers the caller set (e.g. position gains) that a REBOOT resets: written again after one."""

    @property
    def operating_mode(self) -> int:
        """The mode the search runs in: 5 (current-based position) or 4 (extended position, PWM cap)."""
        return 5 if self.current_mode else 4

    def _read_raw(self) -> tuple[int, float, float, int]:
        r = self.bus.sync_read_block(_DXL_READ, [self.motor_id])[self.motor_id]
        v = r["Present_Velocity"] * RPM_UNIT / 60.0 * math.tau
        tau = r["Present_Current"] * self.rating.current_unit_a / self.rating.stall_current_a * self.full_nm
        return r["Present_Position"], v, tau, self._read1("Hardware_Error_Status")

    def _flags(self, bits: int) -> bool:
        if bits & DXL_FATAL_BITS and self._read1("Hardware_Error_Status") & DXL_FATAL_BITS:
            raise DeviceError(f"joint {self.name}: motor {self.motor_id} Hardware_Error_Status {bits:#04x}")
        return bool(bits & OVERLOAD_BIT)  # overload: suspect; the torque stays off until a REBOOT

    def _unwrap(self, present: int) -> float:
        return float(present)  # modes 4 and 5 report multi-turn positions

    def _write_limit(self, limit_nm: float) -> None:
        fraction, top = limit_nm / self.full_nm, self.ceiling_nm / self.full_nm
        if self.current_mode:
            per = self.rating.stall_current_a / self.rating.current_unit_a
            units = min(self.rating.current_limit, round(fraction * per), math.floor(top * per))
            self._sync("Goal_Current", max(1, units))
        else:
            self._sync("Goal_PWM", max(1, min(round(fraction * PWM_FULL), math.floor(top * PWM_FULL))))

    def _goal(self, target_ticks: float) -> int:
        return round(target_ticks)

    def _clear(self) -> None:
        self._sync("Torque_Enable", 0)  # stop pushing first: a motor pressed into a stop may not answer until then
        self.enabled = False
        if self._read1("Hardware_Error_Status"):
            self.bus.reboot(self.motor_id)  # torque is off after it; RAM registers back to their defaults
            self.reboots += 1
            self._sync("Profile_Velocity", 0)
            self._sync("Profile_Acceleration", 0)
            for reg, value in self.ram.items():  # e.g. the arm's position gains
                self._sync(reg, value)
            self._limit_nm = math.nan  # written again by _enable
        s = self.read()
        if s.ok:
            self._enable()


SERVO_DRIVERS: dict[str, type[FeetechJointDriver | DynamixelJointDriver]] = {
    "feetech": FeetechJointDriver,
    "dynamixel": DynamixelJointDriver,
}
"""The stop-search driver class of each servo vendor (constructed as :class:`FeetechJointDriver` documents)."""


def servo_driver_class(vendor: str) -> type[FeetechJointDriver | DynamixelJointDriver]:
    """The driver class of ``vendor``'s servos (``feetech`` or ``dynamixel``).

    E.g. ``servo_driver_class("feetech")(bus, "wrist_roll", 5, rated_nm=1.91, cap_nm=0.48, clock=clock)``.

    Raises:
        UsageError: Unknown vendor (constructing the driver raises it for a cap above the rated torque or a
            Dynamixel model without a rating).
    """
    if vendor not in SERVO_DRIVERS:
        raise UsageError(f"no stop-search driver for vendor {vendor!r}; expected feetech or dynamixel")
    return SERVO_DRIVERS[vendor]
