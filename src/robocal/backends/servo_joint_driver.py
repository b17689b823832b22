"""What the Feetech and Dynamixel stop-search joint drivers share (the tick frame, the period, enable, the loop).

Each vendor's driver lives in its home (:mod:`robocal.backends.feetech.joint_driver`,
:mod:`robocal.backends.dynamixel.joint_driver`) and is reached through ``load_backend`` by the name its
:class:`~robocal.core.vendors.VendorSpec` gives (``joint_driver``). How both drive a servo:
The Feetech and Dynamixel equivalents of :class:`~robocal.backends.robstride.joint_driver.RobstrideJointDriver`:
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
from collections.abc import Mapping
from contextlib import suppress
from typing import Any

from ..core.motor_models import MotorModel, motor_key, rated_motor_model
from ..core.stop_search import Command, StopSample
from ..errors import CalibTimeoutError, UsageError
from .clock import Clock

__all__ = ["WATCHDOG_CHECK_FRACTION", "ServoJointDriver"]

WATCHDOG_CHECK_FRACTION = 0.5
"""A bus exchange whose window (from the start of the driver's previous exchange to the end of this one) is longer
than this fraction of the motor's armed host-loss watchdog time may have let the watchdog trip (robocal was held
up): the driver asks the motor before it hands the reading on (:meth:`ServoJointDriver.send`)."""


def _motor_model(joint: str, bus_model: str, motor: str | None) -> MotorModel:
    """The model table entry of a servo: ``motor`` (a variant such as ``sts3215-12v``) or the bus model.

    Raises:
        UsageError: The model is unknown, or ``motor`` is not a variant of the bus model.
    """
    found = rated_motor_model(joint, motor or bus_model)
    if motor_key(found.bus_model) != motor_key(bus_model):
        raise UsageError(f"joint {joint}: motor {found.name} answers as {found.bus_model!r}, the bus has {bus_model!r}")
    return found


class ServoJointDriver:
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
        self._exchange_start_s = math.nan  # when the previous bus exchange of this driver began (clock time)
        self.watchdog_recoveries = 0
        """How often a tripped host-loss watchdog was found (robocal held up past it), cleared and re-armed."""
        self._init_vendor()

    # -- frame ----------------------------------------------------------------------------------------

    @classmethod
    def prepare_registers(cls, bus: Any, motor_id: int) -> int:
        """Set the registers the search needs before the driver is built (the caller snapshots them first).

        Returns:
            The ``Homing_Offset`` (register units) the search runs with; 0 here (no change).
        """
        del bus, motor_id
        return 0

    def configure(self, ram: Mapping[str, int], *, inverted: bool) -> None:
        """Write the RAM gains the arm holds its pose with and the search's modes, after construction.

        Args:
            ram: Register → value the arm's profile holds this joint with (e.g. position gains).
            inverted: The joint's reading is inverted by the arm's calibration (where the vendor inverts in
                hardware).
        """
        del ram, inverted

    def position_count_rad(self) -> float:
        """One count of ``Present_Position``: a turn over the encoder's resolution (4096 on the STS and X series)."""
        return math.tau / self.res

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

    def _recover_watchdog(self) -> bool:
        """Whether the motor's host-loss watchdog had tripped; if so it is cleared and armed again.

        The vendor's check (Dynamixel ``Bus_Watchdog`` −1); a family without a watchdog never gets here.
        """
        return False

    # -- common ---------------------------------------------------------------------------------------
    def _sync(self, register: str, value: int) -> None:
        self.bus.sync_write(register, {self.motor_id: int(value)})

    def _read1(self, register: str) -> int:
        return int(self.bus.sync_read(register, [self.motor_id])[self.motor_id])

    def read(self) -> StopSample:
        """Read the joint without changing what the motor does (a lost reply gives ``ok=False``).

        Like :meth:`send`, a reading after a silence that may have tripped the motor's host-loss watchdog is
        taken again once the watchdog is cleared and armed again.
        """
        start = self.clock.now()
        s = self._read_sample()
        if self._watchdog_may_have_tripped(start) and self._watchdog_recovered():
            s = self._read_sample()
        return s

    def _watchdog_may_have_tripped(self, start_s: float) -> bool:
        """Whether the motor heard nothing from robocal long enough for its armed watchdog to trip.

        The longest silence the motor saw since the previous exchange lies inside the window from that exchange's
        start to now (robocal may have been descheduled anywhere in it, even while a reply waited for it), so a
        window longer than :data:`WATCHDOG_CHECK_FRACTION` of the watchdog time is checked; the first exchange of
        a driver always is. Restarts the window at ``start_s``.
        """
        previous, self._exchange_start_s = self._exchange_start_s, start_s
        armed_s = getattr(self.bus, "watchdog_armed_s", {}).get(self.motor_id)
        if armed_s is None:
            return False
        return not self.clock.now() - previous <= WATCHDOG_CHECK_FRACTION * armed_s  # NaN: the first exchange

    def _watchdog_recovered(self) -> bool:
        """:meth:`_recover_watchdog`, counted; a lost reply is not a trip (the reading says so)."""
        try:
            tripped = self._recover_watchdog()
        except CalibTimeoutError:
            return False
        self.watchdog_recoveries += int(tripped)
        return tripped

    def _read_sample(self) -> StopSample:
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

        A motor whose host-loss watchdog may have tripped while robocal was held up (a gap between exchanges;
        :meth:`_watchdog_may_have_tripped`) is asked first: a tripped one stopped on its own and refused the goal
        (Dynamixel: it holds where it was), so its reading is no evidence of a stop; the watchdog is cleared and
        armed again and ``cmd`` carried out once more, and only that reading is handed on (issue 26 item 4: a
        scheduling gap is never taken for contact).
        """
        start = self.clock.now()
        s = self._send_once(cmd)
        if cmd.action != "limp" and self._watchdog_may_have_tripped(start) and self._watchdog_recovered():
            s = self._send_once(cmd)
        return s

    def _send_once(self, cmd: Command) -> StopSample:
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
        return self._read_sample()

    def limp(self) -> None:
        """Torque off now (a SYNC_WRITE: no status packet to wait for); never raises."""
        with suppress(Exception):
            self._sync("Torque_Enable", 0)
        self.enabled = False
