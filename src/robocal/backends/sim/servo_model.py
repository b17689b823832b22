"""One simulated Feetech or Dynamixel servo: its control table and the firmware's homing semantics.

Also the bus constants (broadcast id, baud-rate register values).

* Feetech STS: ``Present = (Actual − Homing_Offset) mod 4096`` (``Phase`` bit 4 set: not wrapped).
* Dynamixel X: ``Present = (±Actual) + Homing_Offset`` (``−`` when ``Drive_Mode`` bit 0 is set), wrapped to
  one turn in Position mode (3), unwrapped in Extended Position (4) and Current-based Position (5) modes.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
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
from .._servo_common import ServoModel
from ..dynamixel import DYNAMIXEL_MODELS
from ..feetech import FEETECH_MODELS, SIGN_BITS
from .servo_defaults import FACTORY_DEFAULTS
from .servo_packets import Instruction, dynamixel_status, feetech_status, parse_dynamixel, parse_feetech

if TYPE_CHECKING:
    from .servo_firmware import ServoFirmware

__all__ = ["BAUD_RATES", "BROADCAST_ID", "FACTORY_BAUD", "SIM_SERVO_KINDS", "SimServo", "SimServoKind", "Vendor"]

Vendor = str
"""A vendor's name (a key of :data:`SIM_SERVO_KINDS` and of :data:`robocal.core.vendors.VENDORS`)."""

BROADCAST_ID = 0xFE
"""Packets to this id reach every servo; only PING is answered (by each servo)."""

BAUD_RATES: dict[str, dict[int, int]] = {
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

FACTORY_BAUD: dict[str, int] = {"feetech": 0, "dynamixel": 1}
"""``Baud_Rate`` as shipped: Feetech 1 Mbit/s, Dynamixel X 57600 bit/s."""


@dataclass(frozen=True)
class SimServoKind:
    """How the simulated servos of one vendor differ on the wire and in their firmware (the simulator's adapter).

    The homing rule, where ``Drive_Mode`` lives and the lock register come from the vendor's declaration
    (:mod:`robocal.core.vendors`); this holds what only the simulator needs.

    Attributes:
        vendor: The vendor's name.
        models: Model name → the backend's :class:`~robocal.backends.servo_bus.ServoModel`.
        power_on: ``(register, value)`` a new servo holds, set where its model's table has the register.
        twos_complement: Registers whose value is signed (two's complement); the others read unsigned. Unused
            where signed registers are sign-magnitude (their sign bits are the backend's ``SIGN_BITS``).
        clamps_goal: The firmware clamps ``Goal_Position`` into ``Min/Max_Position_Limit``.
        single_turn_mode: The ``Operating_Mode`` in which Present wraps to one turn (None: the homing rule says).
        address_bytes: Width of the address and length fields of READ / WRITE / SYNC packets.
        parse: Parses one instruction packet (:mod:`.servo_packets`).
        status: Builds one status packet.
        ping_reports_model: PING answers with ``Model_Number`` and ``Firmware_Version``.
        reboot: Knows REBOOT (0x08), which clears a hardware error.
        unknown_instruction_error: Status error byte for an instruction it does not know.
        eeprom_locked_by_torque: EEPROM (addresses below ``Torque_Enable``) refuses writes while the torque is on
            (Access error 7).
        x_series_law: Runs the Dynamixel X control law (:mod:`.servo_firmware`), else the Feetech STS one.
        status_level: The register gating replies (None: every instruction is answered).
        reply_levels: Instruction → the lowest ``status_level`` value at which it is still answered; an
            instruction not listed needs ``full_reply_level``.
        full_reply_level: The ``status_level`` value at which every instruction is answered.
        set_middle: The ``Torque_Enable`` value that makes the present position read half a turn (None: none).
    """

    vendor: str
    models: Mapping[str, ServoModel]
    power_on: tuple[tuple[str, int], ...]
    twos_complement: tuple[str, ...]
    clamps_goal: bool
    single_turn_mode: int | None
    address_bytes: int
    parse: Callable[[bytes | bytearray], tuple[int, Instruction | None]]
    status: Callable[..., bytes]
    ping_reports_model: bool
    reboot: bool
    unknown_instruction_error: int
    eeprom_locked_by_torque: bool
    x_series_law: bool
    status_level: str | None = None
    reply_levels: Mapping[int, int] = field(default_factory=dict)
    full_reply_level: int = 0
    set_middle: int | None = None


SIM_SERVO_KINDS: dict[str, SimServoKind] = {
    "feetech": SimServoKind(
        vendor="feetech",
        models=FEETECH_MODELS,
        power_on=(
            ("Lock", 1),
            ("Baud_Rate", FACTORY_BAUD["feetech"]),
            ("Firmware_Major_Version", 3),
            ("Firmware_Minor_Version", 10),
        ),
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
        x_series_law=False,
        status_level="Response_Status_Level",
        reply_levels={0x01: 0, 0x02: 0, 0x82: 0},  # level 0: PING and READ only; 1: all (Feetech's table)
        full_reply_level=1,
        set_middle=128,
    ),
    "dynamixel": SimServoKind(
        vendor="dynamixel",
        models=DYNAMIXEL_MODELS,
        power_on=(("Operating_Mode", 3), ("Baud_Rate", 3), ("Firmware_Version", 52)),  # 1 Mbit/s, as LeRobot's setup
        twos_complement=(
            "Homing_Offset",
            "Present_Position",
            "Goal_Position",
            "Max_Position_Limit",
            "Min_Position_Limit",
            "Bus_Watchdog",
        ),
        clamps_goal=False,
        single_turn_mode=3,
        address_bytes=2,
        parse=parse_dynamixel,
        status=dynamixel_status,
        ping_reports_model=True,
        reboot=True,
        unknown_instruction_error=2,
        eeprom_locked_by_torque=True,
        x_series_law=True,
        status_level="Status_Return_Level",
        reply_levels={0x01: 0, 0x02: 1},  # 0: PING only; 1: PING and READ; 2: all (the e-Manual)
        full_reply_level=2,
    ),
}
"""Vendor name → how its simulated servos behave (a new simulated vendor is one entry here)."""


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
