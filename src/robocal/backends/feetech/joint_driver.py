"""The Feetech STS servo as a joint driver of the automatic hard-stop calibration (real registers).

The shared loop, frame and safety rules are in :mod:`robocal.backends.servo_joint_driver`; this module holds what
is Feetech's: ``Torque_Limit`` as the cap, ``Status`` bits, the re-homing at the encoder seam.
"""

from __future__ import annotations

import math
from typing import Any

from ...core.lerobot.homing import half_turn_homing_offset
from ...errors import CalibTimeoutError, DeviceError
from ..servo_joint_driver import ServoJointDriver
from ..servo_ratings import OVERLOAD_BIT

__all__ = ["FEETECH_FATAL_BITS", "FEETECH_SUSPECT_BITS", "SEAM_MARGIN_TICKS", "FeetechJointDriver", "mid_turn_offset"]

SEAM_MARGIN_TICKS = 512
"""A Feetech joint this close (ticks) to the 0/res−1 seam is re-homed to mid-turn before the next goal."""
FEETECH_SUSPECT_BITS = OVERLOAD_BIT | 0x08
"""Feetech ``Status`` bits 5 (overload) and 3 (over-current): suspect evidence, cleared by torque off."""
FEETECH_FATAL_BITS = 0x01 | 0x02 | 0x04
"""Feetech ``Status`` bits 0 (voltage), 1 (magnetic sensor), 2 (temperature): the run ends."""
_FEETECH_READ = ("Present_Position", "Present_Velocity", "Present_Load", "Status")  # addresses 56..65


def mid_turn_offset(actual_ticks: int, res: int) -> int:
    """The Feetech ``Homing_Offset`` that makes a joint at ``actual_ticks`` (0..res−1) read mid-turn.

    ``Present = (Actual − Homing_Offset) mod res``; the offset is kept inside the sign-magnitude register's
    ±(res/2 − 1), so the seam is (almost) half a turn away.
    """
    return half_turn_homing_offset(actual_ticks, vendor="feetech", resolution=res)  # the one homing rule


class FeetechJointDriver(ServoJointDriver):
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

    @classmethod
    def prepare_registers(cls, bus: Any, motor_id: int) -> int:
        """Position mode, limits over the whole turn and a ``Homing_Offset`` that puts the seam half a turn away.

        A Feetech position goal must stay inside one turn, so the joint is made to read mid-turn where it is now.

        Returns:
            The ``Homing_Offset`` written (register units).
        """
        res = bus.resolution(motor_id)
        bus.write("Operating_Mode", motor_id, 0)
        bus.write("Min_Position_Limit", motor_id, 0)
        bus.write("Max_Position_Limit", motor_id, res - 1)
        present = bus.read("Present_Position", motor_id)
        offset = mid_turn_offset((present + bus.read("Homing_Offset", motor_id)) % res, res)
        bus.write("Homing_Offset", motor_id, offset)
        bus.write("Goal_Velocity", motor_id, 0)
        bus.write("Acceleration", motor_id, 0)
        return offset

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
