"""One simulated Feetech or Dynamixel servo: its control table and the firmware's homing semantics.

Also the bus constants (broadcast id, baud-rate register values).

* Feetech STS: ``Present = (Actual − Homing_Offset) mod 4096`` (``Phase`` bit 4 set: not wrapped).
* Dynamixel X: ``Present = (±Actual) + Homing_Offset`` (``−`` when ``Drive_Mode`` bit 0 is set), wrapped to
  one turn in Position mode (3), unwrapped in Extended Position (4) and Current-based Position (5) modes.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Literal

from ...core.lerobot import (
    decode_sign_magnitude,
    decode_twos_complement,
    encode_sign_magnitude,
    encode_twos_complement,
)
from ...errors import UsageError
from ..dynamixel import DYNAMIXEL_MODELS
from ..feetech import FEETECH_MODELS, SIGN_BITS

if TYPE_CHECKING:
    from .servo_firmware import ServoFirmware

__all__ = ["BAUD_RATES", "BROADCAST_ID", "FACTORY_BAUD", "SimServo", "Vendor"]

Vendor = Literal["feetech", "dynamixel"]

BROADCAST_ID = 0xFE
"""Packets to this id reach every servo; only PING is answered (by each servo)."""

BAUD_RATES: dict[Vendor, dict[int, int]] = {
    "feetech": {
        0: 1_000_000,
        1: 500_000,
        2: 250_000,
        3: 128_000,
        4: 115_200,
        5: 57_600,
        6: 38_400,
        7: 19_200,
    },
    "dynamixel": {
        0: 9_600,
        1: 57_600,
        2: 115_200,
        3: 1_000_000,
        4: 2_000_000,
        5: 3_000_000,
        6: 4_000_000,
        7: 4_500_000,
    },
}
"""``Baud_Rate`` register value → bit/s (Feetech STS/SCS; Dynamixel X series)."""

FACTORY_BAUD: dict[Vendor, int] = {"feetech": 0, "dynamixel": 1}
"""``Baud_Rate`` as shipped: Feetech 1 Mbit/s, Dynamixel X 57600 bit/s."""


@dataclass
class SimServo:
    """One simulated servo.

    Attributes:
        motor_id: Bus id.
        model: Model name (``"sts3215"``, ``"xl330-m288"``, ...).
        actual_ticks: Physical position, ticks, continuous across turns (the firmware sees it modulo a turn).
        stop_low_ticks: Lower hard stop, ticks (same frame as ``actual_ticks``).
        stop_high_ticks: Upper hard stop, ticks.
    """

    motor_id: int
    model: str
    actual_ticks: float = 2048.0
    stop_low_ticks: float = -1e9
    stop_high_ticks: float = 1e9
    regs: bytearray = field(default_factory=lambda: bytearray(256))
    attached: bool = True
    """Plugged into the bus (an unplugged servo hears nothing)."""
    last_write: str = ""
    """What the last client wrote to this servo (``"Goal_Position=2048"``), for the live view."""
    last_write_time: float = 0.0
    """``time.monotonic()`` of :attr:`last_write`."""
    position_reads: int = 0
    """Reads (READ, SYNC_READ) answered whose span holds ``Present_Position``."""
    firmware: ServoFirmware | None = None
    """Physics and control law (:mod:`.servo_firmware`); None: the shaft is placed from outside."""

    @property
    def vendor(self) -> Vendor:
        """``"feetech"`` or ``"dynamixel"``."""
        return "feetech" if self.model in FEETECH_MODELS else "dynamixel"

    def __post_init__(self) -> None:
        if self.model not in FEETECH_MODELS and self.model not in DYNAMIXEL_MODELS:
            raise UsageError(f"simulated servo model {self.model!r} is unknown")
        self.actual_ticks = min(self.stop_high_ticks, max(self.stop_low_ticks, self.actual_ticks))
        spec = FEETECH_MODELS[self.model] if self.vendor == "feetech" else DYNAMIXEL_MODELS[self.model]
        self.table = spec.table
        self.big_endian = spec.protocol == 1
        self.resolution = spec.resolution
        self.set_reg("Model_Number", spec.model_number)
        self.set_reg("ID", self.motor_id)
        self.set_reg("Max_Position_Limit", spec.resolution - 1)
        if self.vendor == "feetech":
            self.set_reg("Lock", 1)
            self.set_reg("Baud_Rate", FACTORY_BAUD["feetech"])
            if "Firmware_Major_Version" in spec.table:
                self.set_reg("Firmware_Major_Version", 3)
                self.set_reg("Firmware_Minor_Version", 10)
            if "Phase" in spec.table:
                self.set_reg("Phase", 0)
        else:
            self.set_reg("Operating_Mode", 3)
            self.set_reg("Baud_Rate", 3)  # 1 Mbit/s, as LeRobot's setup leaves it
            self.set_reg("Firmware_Version", 52)

    # ---------------------------------------------------------------------------------- register access
    def _pack(self, value: int, size: int) -> bytes:
        return int(value).to_bytes(size, "big" if self.big_endian else "little")

    def _signed_to_raw(self, name: str, value: int, size: int) -> int:
        if self.vendor == "feetech":
            if not self.big_endian and name in SIGN_BITS:
                return encode_sign_magnitude(value, SIGN_BITS[name])
            return int(value) & ((1 << (8 * size)) - 1)
        return encode_twos_complement(value, size) if value < 0 else int(value)

    def set_reg(self, name: str, value: int) -> None:
        """Set a register by name from a signed value (encoded like the firmware)."""
        addr, size = self.table[name]
        self.regs[addr : addr + size] = self._pack(self._signed_to_raw(name, value, size), size)

    def get_reg(self, name: str) -> int:
        """Decoded value of a register by name."""
        addr, size = self.table[name]
        raw = int.from_bytes(self.regs[addr : addr + size], "big" if self.big_endian else "little")
        if self.vendor == "feetech":
            if not self.big_endian and name in SIGN_BITS:
                return decode_sign_magnitude(raw, SIGN_BITS[name])
            return raw
        if name in (
            "Homing_Offset",
            "Present_Position",
            "Goal_Position",
            "Max_Position_Limit",
            "Min_Position_Limit",
        ):
            return decode_twos_complement(raw, size)
        return raw

    @property
    def bus_id(self) -> int:
        """The id the servo answers to now (its ``ID`` register)."""
        return self.regs[self.table["ID"][0]]

    @property
    def baudrate(self) -> int:
        """Bit/s the servo listens at now (its ``Baud_Rate`` register; unknown values read as 1 Mbit/s)."""
        return BAUD_RATES[self.vendor].get(self.regs[self.table["Baud_Rate"][0]], 1_000_000)  # one byte

    def factory_reset(self) -> None:
        """ID 1, the vendor's shipping baud rate, no homing offset, full-turn limits (a new servo)."""
        self.set_reg("ID", 1)
        self.set_reg("Baud_Rate", FACTORY_BAUD[self.vendor])
        if "Homing_Offset" in self.table:
            self.set_reg("Homing_Offset", 0)
        self.set_reg("Min_Position_Limit", 0)
        self.set_reg("Max_Position_Limit", self.resolution - 1)

    def eeprom_snapshot(self) -> dict[str, int]:
        """Calibration-relevant EEPROM values (Homing_Offset, limits, Drive_Mode where present)."""
        names = ["Homing_Offset", "Min_Position_Limit", "Max_Position_Limit", "Drive_Mode"]
        return {n: self.get_reg(n) for n in names if n in self.table}

    # ------------------------------------------------------------------------------------------ physics
    def move_to(self, actual_ticks: float) -> None:
        """Move the output shaft (by hand or by torque); hard stops hold it."""
        self.actual_ticks = float(min(self.stop_high_ticks, max(self.stop_low_ticks, actual_ticks)))
        if self.firmware is not None:
            self.firmware.plant.set_state(self.firmware.rad(self.actual_ticks))

    def present_ticks(self, noise: int = 0) -> int:
        """The Present_Position the firmware would report now."""
        actual = round(self.actual_ticks) + noise
        res = self.resolution
        if self.vendor == "feetech":
            if "Homing_Offset" not in self.table:
                return actual % res
            present = actual - self.get_reg("Homing_Offset")
            if "Phase" in self.table and self.get_reg("Phase") & 0x10:
                return present
            return present % res
        signed = -actual if self.get_reg("Drive_Mode") & 1 else actual
        present = signed + self.get_reg("Homing_Offset")
        if self.get_reg("Operating_Mode") == 3:
            return present % res
        return present

    def goal_to_actual(self, goal_ticks: int) -> float:
        """Actual position that makes Present equal ``goal_ticks`` (nearest to the current position)."""
        res = self.resolution
        if self.vendor == "feetech":
            offset = self.get_reg("Homing_Offset") if "Homing_Offset" in self.table else 0
            lo, hi = self.get_reg("Min_Position_Limit"), self.get_reg("Max_Position_Limit")
            goal = min(hi, max(lo, goal_ticks))
            target = goal + offset
            turns = round((self.actual_ticks - target) / res)
            return float(target + turns * res)
        sign = -1 if self.get_reg("Drive_Mode") & 1 else 1
        target = sign * (goal_ticks - self.get_reg("Homing_Offset"))
        if self.get_reg("Operating_Mode") == 3:
            turns = round((self.actual_ticks - target) / res)
            target += turns * res
        return float(target)
