"""The Dynamixel X servo as a joint driver of the automatic hard-stop calibration (real registers).

The shared loop, frame and safety rules are in :mod:`robocal.backends.servo_joint_driver`; this module holds what
is Dynamixel's: ``Goal_Current`` (or ``Goal_PWM``) as the cap, ``Hardware_Error_Status`` and the REBOOT, and the
check of a ``Bus_Watchdog`` that tripped while robocal was held up (cleared and armed again before the reading is
used: :meth:`~robocal.backends.servo_joint_driver.ServoJointDriver.send`).
"""

from __future__ import annotations

import math
from collections.abc import Mapping

from ...errors import DeviceError, UsageError
from ..servo_joint_driver import ServoJointDriver
from ..servo_ratings import OVERLOAD_BIT, PWM_FULL, RATINGS, RPM_UNIT

__all__ = ["DXL_FATAL_BITS", "DynamixelJointDriver", "dynamixel_current_mode"]

DXL_FATAL_BITS = 0x01 | 0x04 | 0x08 | 0x10
"""Dynamixel ``Hardware_Error_Status`` bits 0 (voltage), 2 (overheating), 3 (encoder), 4 (electrical shock)."""
_DXL_READ = ("Present_Current", "Present_Velocity", "Present_Position")  # addresses 126..135


def dynamixel_current_mode(model: str) -> bool:
    """Whether a Dynamixel model senses current (current-based position mode 5 with ``Goal_Current``)."""
    rating = RATINGS.get(model)
    return rating is not None and rating.current_limit > 0


class DynamixelJointDriver(ServoJointDriver):
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

    def configure(self, ram: Mapping[str, int], *, inverted: bool) -> None:
        """Hold gains, the search's operating mode, ``Drive_Mode`` as the arm's calibration sets it, offset 0."""
        self.ram = dict(ram)
        bus, i = self.bus, self.motor_id
        for reg, value in self.ram.items():
            bus.write(reg, i, value)
        bus.write("Operating_Mode", i, self.operating_mode)
        bus.write("Drive_Mode", i, 1 if inverted else 0)
        bus.write("Homing_Offset", i, 0)
        bus.write("Profile_Velocity", i, 0)
        bus.write("Profile_Acceleration", i, 0)

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

    def _recover_watchdog(self) -> bool:
        """``Bus_Watchdog`` −1 (tripped: the servo stopped and refuses goals): written 0 (cleared), then armed again."""
        if self._read1("Bus_Watchdog") != -1:
            return False
        armed_s = self.bus.watchdog_armed_s[self.motor_id]
        self._sync("Bus_Watchdog", 0)
        self.bus.arm_watchdog([self.motor_id], armed_s)
        return True

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
