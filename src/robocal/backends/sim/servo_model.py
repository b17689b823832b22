"""One simulated Feetech or Dynamixel servo: its control table and the firmware's homing semantics.

Also the bus constants (broadcast id, baud-rate register values).

* Feetech STS: ``Present = (Actual − Homing_Offset) mod 4096`` (``Phase`` bit 4 set: not wrapped).
* Dynamixel X: ``Present = (±Actual) + Homing_Offset`` (``−`` when ``Drive_Mode`` bit 0 is set), wrapped to
  one turn in Position mode (3), unwrapped in Extended Position (4) and Current-based Position (5) modes.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

from ...core.lerobot import (
    decode_sign_magnitude,
    decode_twos_complement,
    encode_sign_magnitude,
    encode_twos_complement,
)
from ...core.vendors import VendorSpec, vendor_spec
from ...errors import UsageError
from ..dynamixel.sim import DYNAMIXEL_SIM
from ..feetech import SIGN_BITS
from ..feetech.sim import FEETECH_SIM
from .servo_defaults import FACTORY_DEFAULTS
from .servo_kind import SimServoKind

if TYPE_CHECKING:
    from .servo_firmware import ServoFirmware

__all__ = ["BAUD_RATES", "BROADCAST_ID", "FACTORY_BAUD", "SIM_SERVO_KINDS", "SimServo", "SimServoKind", "Vendor"]

Vendor = str
"""A vendor's name (a key of :data:`SIM_SERVO_KINDS` and of :data:`robocal.core.vendors.VENDORS`)."""

BROADCAST_ID = 0xFE
"""Packets to this id reach every servo; only PING is answered (by each servo)."""




SIM_SERVO_KINDS: dict[str, SimServoKind] = {kind.vendor: kind for kind in (FEETECH_SIM, DYNAMIXEL_SIM)}
"""Vendor name → how its simulated servos behave (each declared in the vendor's home, ``backends/<vendor>/sim.py``;
a new simulated servo vendor is one entry here)."""
BAUD_RATES: dict[str, Mapping[int, int]] = {v: k.baud_rates for v, k in SIM_SERVO_KINDS.items()}
"""``Baud_Rate`` register value → bit/s, per vendor."""
FACTORY_BAUD: dict[str, int] = {v: k.factory_baud for v, k in SIM_SERVO_KINDS.items()}
"""``Baud_Rate`` as shipped, per vendor (Feetech 1 Mbit/s, Dynamixel X 57600 bit/s)."""



def _kind_of_model(model: str) -> SimServoKind:
    """The simulated vendor whose backend lists ``model``.

    Raises:
        UsageError: No simulated vendor has that model.
    """
    for kind in SIM_SERVO_KINDS.values():
        if model in kind.models:
            return kind
    raise UsageError(f"simulated servo model {model!r} is unknown")


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
    watchdog_rx_s: float | None = None
    """When this servo last heard an instruction packet (the bus's clock), for ``Bus_Watchdog``."""
    watchdog_trips: list[tuple[float, float]] = field(default_factory=list)
    """(last instruction, trip time) of every ``Bus_Watchdog`` trip (:mod:`.servo_watchdog`)."""

    @property
    def vendor(self) -> Vendor:
        """The vendor's name (``"feetech"``, ``"dynamixel"``)."""
        return self.kind.vendor

    def __post_init__(self) -> None:
        self.kind: SimServoKind = _kind_of_model(self.model)
        self.vendor_spec: VendorSpec = vendor_spec(self.kind.vendor)
        self.actual_ticks = min(self.stop_high_ticks, max(self.stop_low_ticks, self.actual_ticks))
        spec = self.kind.models[self.model]
        self.table = spec.table
        self.big_endian = spec.protocol == 1
        self.resolution = spec.resolution
        for addr, (size, value) in FACTORY_DEFAULTS.get(self.model, {}).items():
            self.regs[addr : addr + size] = self._pack(value, size)
        self.set_reg("Model_Number", spec.model_number)
        self.set_reg("ID", self.motor_id)
        self.set_reg("Max_Position_Limit", spec.resolution - 1)
        for name, value in self.kind.power_on:
            if name in spec.table:
                self.set_reg(name, value)

    # ---------------------------------------------------------------------------------- register access
    def _pack(self, value: int, size: int) -> bytes:
        return int(value).to_bytes(size, "big" if self.big_endian else "little")

    @property
    def _sign_magnitude(self) -> bool:
        """Signed registers are sign-magnitude (else two's complement), as the vendor declares its offset."""
        return self.vendor_spec.homing_rule().encoding == "sign-magnitude"

    def _signed_to_raw(self, name: str, value: int, size: int) -> int:
        if self._sign_magnitude:
            if not self.big_endian and name in SIGN_BITS:
                return encode_sign_magnitude(value, SIGN_BITS[name])
            return int(value) & ((1 << (8 * size)) - 1)
        return encode_twos_complement(value, size) if value < 0 else int(value)

    def encode_reading(self, name: str, value: int) -> int:
        """A reading (``Present_Position``) as the firmware stores it, saturated to the register's reach."""
        size = self.table[name][1]
        if self._sign_magnitude:
            if not self.big_endian and name in SIGN_BITS:
                limit = (1 << SIGN_BITS[name]) - 1
                return encode_sign_magnitude(max(-limit, min(limit, value)), SIGN_BITS[name])
            return int(value) & ((1 << (8 * size)) - 1)
        return encode_twos_complement(value, size)

    def set_reg(self, name: str, value: int) -> None:
        """Set a register by name from a signed value (encoded like the firmware)."""
        addr, size = self.table[name]
        self.regs[addr : addr + size] = self._pack(self._signed_to_raw(name, value, size), size)

    def get_reg(self, name: str) -> int:
        """Decoded value of a register by name."""
        addr, size = self.table[name]
        raw = int.from_bytes(self.regs[addr : addr + size], "big" if self.big_endian else "little")
        if self._sign_magnitude:
            if not self.big_endian and name in SIGN_BITS:
                return decode_sign_magnitude(raw, SIGN_BITS[name])
            return raw
        if name in self.kind.twos_complement:
            return decode_twos_complement(raw, size)
        return raw

    def out_of_range(self, addr: int, data: bytes) -> str | None:
        """The first register the write of ``data`` at ``addr`` would set outside its range (None: none)."""
        for name, (lo, hi) in self.kind.value_ranges.items():
            if name not in self.table:
                continue
            a, size = self.table[name]
            if addr <= a and a + size <= addr + len(data):
                raw = int.from_bytes(data[a - addr : a - addr + size], "big" if self.big_endian else "little")
                value = decode_twos_complement(raw, size) if name in self.kind.twos_complement else raw
                if not lo <= value <= hi:
                    return name
        return None

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

    def answers(self, inst: int) -> bool:
        """The servo sends a status packet for instruction ``inst`` at its status return level now."""
        name = self.kind.status_level
        if name is None or name not in self.table:
            return True
        return self.get_reg(name) >= self.kind.reply_levels.get(inst, self.kind.full_reply_level)

    @property
    def drives(self) -> bool:
        """Torque is on and may be nonzero (Feetech ``Torque_Limit`` 0: no torque, the shaft stays put)."""
        on = bool(self.get_reg("Torque_Enable"))
        return on and ("Torque_Limit" not in self.table or self.get_reg("Torque_Limit") > 0)

    def apply_set_middle(self, addr: int, data: bytes) -> bytes:
        """Feetech's set middle, if ``data`` written at ``addr`` sets ``Torque_Enable`` to 128; the data to store.

        The firmware rewrites ``Homing_Offset`` so that ``Present_Position`` reads half a turn (2048) at the
        shaft's present angle (wrapped into the offset's ±2047; at an angle that needs −2048 it reads 2047), and
        ``Torque_Enable`` reads 0 afterwards: 128 does not switch the torque on (docs/sim.md).
        """
        torque = self.table["Torque_Enable"][0]
        value = self.kind.set_middle
        if value is None or "Homing_Offset" not in self.table or not addr <= torque < addr + len(data):
            return data
        if data[torque - addr] != value:
            return data
        self.set_reg("Homing_Offset", 0)
        half = self.resolution // 2
        wrapped = (self.present_ticks() - half + half) % self.resolution - half  # the reading to take away
        offset = -self.vendor_spec.homing_rule().offset_sign * wrapped
        limit = (1 << SIGN_BITS["Homing_Offset"]) - 1
        self.set_reg("Homing_Offset", max(-limit, min(limit, offset)))
        stored = bytearray(data)
        stored[torque - addr] = 0
        return bytes(stored)

    # ------------------------------------------------------------------------------------------ physics
    def move_to(self, actual_ticks: float) -> None:
        """Move the output shaft (by hand or by torque); hard stops hold it."""
        self.actual_ticks = float(min(self.stop_high_ticks, max(self.stop_low_ticks, actual_ticks)))
        if self.firmware is not None:
            self.firmware.plant.set_state(self.firmware.rad(self.actual_ticks))

    @property
    def _drive_sign(self) -> int:
        """−1 where a hardware ``Drive_Mode`` bit 0 inverts the reading, else 1."""
        inverted = self.vendor_spec.drive_mode_in_hardware and self.get_reg("Drive_Mode") & 1
        return -1 if inverted else 1

    def _wraps_now(self) -> bool:
        """Present is reported modulo one turn with the registers as they are."""
        if self.vendor_spec.multi_turn_phase_bit and "Phase" in self.table and self.get_reg("Phase") & 0x10:
            return False
        mode = self.kind.single_turn_mode
        if mode is not None:
            return bool(self.get_reg("Operating_Mode") == mode)
        return self.vendor_spec.homing_rule().wraps_per_turn

    def present_ticks(self, noise: int = 0) -> int:
        """The Present_Position the firmware would report now."""
        actual = round(self.actual_ticks) + noise
        res = self.resolution
        if "Homing_Offset" not in self.table:
            return actual % res
        present = int(self.vendor_spec.homing_rule().present(self._drive_sign * actual, self.get_reg("Homing_Offset")))
        return present % res if self._wraps_now() else present

    def goal_to_actual(self, goal_ticks: int) -> float:
        """Actual position that makes Present equal ``goal_ticks`` (nearest to the current position)."""
        res = self.resolution
        offset = self.get_reg("Homing_Offset") if "Homing_Offset" in self.table else 0
        goal = goal_ticks
        if self.kind.clamps_goal:
            lo, hi = self.get_reg("Min_Position_Limit"), self.get_reg("Max_Position_Limit")
            goal = min(hi, max(lo, goal_ticks))
        target = self._drive_sign * (goal - self.vendor_spec.homing_rule().offset_sign * offset)
        if self.vendor_spec.homing_rule().wraps_per_turn or self._wraps_now():  # known modulo a turn
            turns = round((self.actual_ticks - target) / res)
            target += turns * res
        return float(target)
