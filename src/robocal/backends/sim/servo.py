"""Simulated Feetech and Dynamixel servos answering real packets on a pseudo-terminal.

A :class:`SimServoBus` opens a pty (``os.openpty()``, raw mode) and runs one thread that parses instruction
packets written by the unmodified vendor SDK (Feetech protocol 0/1 with checksum; Dynamixel protocol 2.0 with
CRC-16 and byte stuffing) and answers with status packets. Each :class:`SimServo` has a control table
(bytes), a physical position in ticks (continuous, multi-turn) limited by hard stops, optional read noise, and
the firmware's homing semantics:

* Feetech STS: ``Present = (Actual − Homing_Offset) mod 4096`` (``Phase`` bit 4 set: not wrapped).
* Dynamixel X: ``Present = (±Actual) + Homing_Offset`` (``−`` when ``Drive_Mode`` bit 0 is set), wrapped to
  one turn in Position mode (3), unwrapped in Extended Position (4) and Current-based Position (5) modes.

Dynamixel EEPROM (addresses < 64) is read-only while torque is on (Access error); Feetech EEPROM writes are
refused with Lock = 1 only when ``enforce_lock`` is set.

Bus behaviour as on hardware: a servo answers the id in its ``ID`` register (not the one it was built with),
only while it is plugged in (:attr:`SimServo.attached`) and only at its own baud rate (``Baud_Rate`` register).
A pty carries no baud rate, so the simulator reads the speed the client set on the terminal (``TCGETS2``) and
ignores packets sent at another speed. A write to ``ID`` or ``Baud_Rate`` is acknowledged with the old id at
the old speed, then takes effect. Broadcast PING (id 0xFE) is answered by every servo on the bus, in id order.
"""

from __future__ import annotations

import contextlib
import fcntl
import os
import select
import struct
import threading
import time
import tty
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Literal

import numpy as np

from ...core.lerobot import (
    decode_sign_magnitude,
    decode_twos_complement,
    encode_sign_magnitude,
    encode_twos_complement,
)
from ...errors import UsageError
from ..dynamixel import DYNAMIXEL_MODELS, X_TABLE
from ..feetech import FEETECH_MODELS, SIGN_BITS

__all__ = ["BAUD_RATES", "BROADCAST_ID", "SimServo", "SimServoBus", "dxl_crc16"]

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

_TCGETS2 = 0x802C542A  # _IOR('T', 0x2A, struct termios2) on x86 and the generic ioctl ABI (arm, arm64, riscv)


def _crc_table() -> list[int]:
    table = []
    for i in range(256):
        crc = i << 8
        for _ in range(8):
            crc = ((crc << 1) ^ 0x8005) if crc & 0x8000 else (crc << 1)
        table.append(crc & 0xFFFF)
    return table


_CRC_TABLE = _crc_table()


def dxl_crc16(data: Iterable[int]) -> int:
    """Dynamixel protocol 2.0 CRC-16 (polynomial 0x8005, initial 0)."""
    crc = 0
    for b in data:
        i = ((crc >> 8) ^ b) & 0xFF
        crc = ((crc << 8) ^ _CRC_TABLE[i]) & 0xFFFF
    return crc


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

    @property
    def vendor(self) -> Vendor:
        """``"feetech"`` or ``"dynamixel"``."""
        return "feetech" if self.model in FEETECH_MODELS else "dynamixel"

    def __post_init__(self) -> None:
        if self.model not in FEETECH_MODELS and self.model not in DYNAMIXEL_MODELS:
            raise UsageError(f"simulated servo model {self.model!r} is unknown")
        self.actual_ticks = min(self.stop_high_ticks, max(self.stop_low_ticks, self.actual_ticks))
        if self.vendor == "feetech":
            number, res, protocol, table = FEETECH_MODELS[self.model]
            self.table = table
            self.big_endian = protocol == 1
            self.resolution = res
            self.set_reg("Model_Number", number)
            self.set_reg("ID", self.motor_id)
            self.set_reg("Max_Position_Limit", res - 1)
            self.set_reg("Lock", 1)
            self.set_reg("Baud_Rate", FACTORY_BAUD["feetech"])
            if "Firmware_Major_Version" in table:
                self.set_reg("Firmware_Major_Version", 3)
                self.set_reg("Firmware_Minor_Version", 10)
            if "Phase" in table:
                self.set_reg("Phase", 0)
        else:
            number, res = DYNAMIXEL_MODELS[self.model]
            self.table = X_TABLE
            self.big_endian = False
            self.resolution = res
            self.set_reg("Model_Number", number)
            self.set_reg("ID", self.motor_id)
            self.set_reg("Operating_Mode", 3)
            self.set_reg("Max_Position_Limit", res - 1)
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
        return BAUD_RATES[self.vendor].get(self.get_reg("Baud_Rate"), 1_000_000)

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


class SimServoBus:
    """Servos of one vendor behind one pseudo-terminal, answered by a background thread.

    Args:
        servos: The servos on the bus (one vendor).
        noise_ticks: Uniform integer read noise ±``noise_ticks`` on Present_Position.
        seed: Seed of the noise generator.
        enforce_lock: Refuse Feetech EEPROM writes while Lock = 1 (status error bit 0x08).

    Use as a context manager; :attr:`port` is the path to hand to the SDK.
    """

    def __init__(
        self, servos: Sequence[SimServo], *, noise_ticks: int = 0, seed: int = 0, enforce_lock: bool = False
    ) -> None:
        vendors = {s.vendor for s in servos}
        if len(vendors) != 1:
            raise UsageError("a simulated bus holds servos of exactly one vendor")
        self.vendor: Vendor = vendors.pop()
        self.servos: dict[int, SimServo] = {s.motor_id: s for s in servos}
        self.noise_ticks = noise_ticks
        self.enforce_lock = enforce_lock
        self._rng = np.random.default_rng(seed)
        self._lock = threading.RLock()
        self._stop = threading.Event()
        self._master, self._slave = os.openpty()
        tty.setraw(self._master)
        tty.setraw(self._slave)
        self.port = os.ttyname(self._slave)
        self._thread = threading.Thread(target=self._run, name=f"sim-servo-{self.port}", daemon=True)
        self.instructions = 0
        self.silent_ids: set[int] = set()
        """Ids that do not answer (to test timeouts)."""
        self.corrupt_next = 0
        """Number of upcoming status packets sent with a wrong checksum."""

    # ------------------------------------------------------------------------------------ life cycle
    def start(self) -> SimServoBus:
        """Start answering packets."""
        self._thread.start()
        return self

    def stop(self) -> None:
        """Stop the thread (bounded wait) and close the pty."""
        self._stop.set()
        if self._thread.is_alive():
            self._thread.join(timeout=2.0)
        for fd in (self._master, self._slave):
            with contextlib.suppress(OSError):
                os.close(fd)

    def __enter__(self) -> SimServoBus:
        return self.start()

    def __exit__(self, *exc: object) -> None:
        self.stop()

    @property
    def lock(self) -> threading.RLock:
        """Lock guarding servo state (hold it while moving joints from another thread)."""
        return self._lock

    # ----------------------------------------------------------------------------------------- thread
    def _run(self) -> None:
        buf = bytearray()
        while not self._stop.is_set():
            try:
                ready, _, _ = select.select([self._master], [], [], 0.02)
            except (OSError, ValueError):
                return
            if not ready:
                continue
            try:
                chunk = os.read(self._master, 4096)
            except OSError:
                return
            buf.extend(chunk)
            while True:
                consumed = self._parse(buf)
                if consumed == 0:
                    break
                del buf[:consumed]

    def _send(self, data: bytes) -> None:
        with contextlib.suppress(OSError):
            os.write(self._master, data)

    def _parse(self, buf: bytearray) -> int:
        """Handle one packet at the start of ``buf``; return bytes consumed (0 = need more)."""
        if self.vendor == "feetech":
            return self._parse_feetech(buf)
        return self._parse_dynamixel(buf)

    # -------------------------------------------------------------------------------------- feetech
    def _parse_feetech(self, buf: bytearray) -> int:
        start = buf.find(b"\xff\xff")
        if start < 0:
            return max(0, len(buf) - 1)
        if start > 0:
            return start
        if len(buf) < 4:
            return 0
        length = buf[3]
        total = length + 4
        if len(buf) < total:
            return 0
        pkt = bytes(buf[:total])
        if (~sum(pkt[2:-1])) & 0xFF != pkt[-1]:
            return 1  # bad checksum: resync
        self.instructions += 1
        self._handle(pkt[2], pkt[4], pkt[5:-1])
        return total

    def _status_feetech(self, motor_id: int, error: int, params: bytes) -> bytes:
        body = bytes([motor_id, len(params) + 2, error]) + params
        chk = (~sum(body)) & 0xFF
        if self.corrupt_next > 0:
            self.corrupt_next -= 1
            chk ^= 0xFF
        return b"\xff\xff" + body + bytes([chk])

    # ------------------------------------------------------------------------------------ dynamixel
    def _parse_dynamixel(self, buf: bytearray) -> int:
        start = buf.find(b"\xff\xff\xfd\x00")
        if start < 0:
            return max(0, len(buf) - 3)
        if start > 0:
            return start
        if len(buf) < 7:
            return 0
        length = buf[5] | (buf[6] << 8)
        total = 7 + length
        if len(buf) < total:
            return 0
        pkt = bytes(buf[:total])
        if dxl_crc16(pkt[:-2]) != (pkt[-2] | (pkt[-1] << 8)):
            return 1
        body = pkt[7:-2]  # instruction + params, stuffed
        unstuffed = bytearray()
        i = 0
        while i < len(body):
            unstuffed.append(body[i])
            stuffed_fd = body[i] == 0xFD and i >= 2 and body[i - 1] == 0xFF and body[i - 2] == 0xFF
            if stuffed_fd and i + 1 < len(body) and body[i + 1] == 0xFD:
                i += 1
            i += 1
        self.instructions += 1
        self._handle(pkt[4], unstuffed[0], bytes(unstuffed[1:]))
        return total

    def _status_dynamixel(self, motor_id: int, error: int, params: bytes) -> bytes:
        raw = bytes([0x55, error]) + params
        stuffed = bytearray()
        for b in raw:
            stuffed.append(b)
            if b == 0xFD and len(stuffed) >= 3 and stuffed[-2] == 0xFF and stuffed[-3] == 0xFF:
                stuffed.append(0xFD)
        # a header-like FF FF FD spanning the id/length fields cannot occur in practice
        length = len(stuffed) + 2
        head = bytes([0xFF, 0xFF, 0xFD, 0x00, motor_id, length & 0xFF, length >> 8]) + bytes(stuffed)
        crc = dxl_crc16(head)
        if self.corrupt_next > 0:
            self.corrupt_next -= 1
            crc ^= 0xFFFF
        return head + bytes([crc & 0xFF, crc >> 8])

    # ------------------------------------------------------------------------------------- semantics
    def _status(self, motor_id: int, error: int, params: bytes = b"") -> bytes:
        if self.vendor == "feetech":
            return self._status_feetech(motor_id, error, params)
        return self._status_dynamixel(motor_id, error, params)

    def _refresh(self, servo: SimServo) -> None:
        noise = int(self._rng.integers(-self.noise_ticks, self.noise_ticks + 1)) if self.noise_ticks else 0
        present = servo.present_ticks(noise)
        addr, size = servo.table["Present_Position"]
        if servo.vendor == "feetech":
            if not servo.big_endian:
                raw = encode_sign_magnitude(max(-32767, min(32767, present)), 15)
            else:
                raw = present & 0xFFFF
        else:
            raw = encode_twos_complement(present, 4)
        servo.regs[addr : addr + size] = servo._pack(raw, size)
        mov_addr, _ = servo.table["Moving"]
        servo.regs[mov_addr] = 0

    def _read(self, servo: SimServo, addr: int, size: int) -> bytes:
        self._refresh(servo)
        return bytes(servo.regs[addr : addr + size])

    def _write(self, servo: SimServo, addr: int, data: bytes) -> int:
        """Apply a register write; return the status error byte."""
        if servo.vendor == "dynamixel":
            torque_addr = X_TABLE["Torque_Enable"][0]
            if addr < torque_addr and servo.regs[torque_addr]:
                return 7  # Access error: EEPROM is locked while torque is on
        else:
            lock_addr = servo.table["Lock"][0]
            torque_addr = servo.table["Torque_Enable"][0]
            if self.enforce_lock and addr < torque_addr and servo.regs[lock_addr]:
                return 0x08
        servo.regs[addr : addr + len(data)] = data
        goal_addr, _goal_size = servo.table["Goal_Position"]
        torque_addr = servo.table["Torque_Enable"][0]
        if servo.regs[torque_addr] and addr <= goal_addr < addr + len(data):
            servo.move_to(servo.goal_to_actual(servo.get_reg("Goal_Position")))
        return 0

    def client_baudrate(self) -> int | None:
        """Bit/s the client last set on the terminal (``TCGETS2``), or None where it cannot be read."""
        buf = bytearray(44)
        try:
            fcntl.ioctl(self._slave, _TCGETS2, buf)
        except (OSError, ValueError):
            return None
        return int(struct.unpack_from("<I", buf, 40)[0])

    def on_bus(self, motor_id: int) -> list[SimServo]:
        """Servos that hear a packet for ``motor_id`` now: plugged in, at the client's speed, with that id."""
        speed = self.client_baudrate()
        return [
            s
            for s in self.servos.values()
            if s.attached
            and (speed is None or s.baudrate == speed)
            and (motor_id == BROADCAST_ID or s.bus_id == motor_id)
        ]

    def _handle(self, motor_id: int, inst: int, params: bytes) -> None:
        try:
            self._handle_unchecked(motor_id, inst, params)
        except (IndexError, ValueError):  # a malformed instruction gets no answer, like a real servo
            return

    def _ping_params(self, servo: SimServo) -> bytes:
        if servo.vendor == "dynamixel":
            number = servo.get_reg("Model_Number")
            return bytes([number & 0xFF, number >> 8, servo.get_reg("Firmware_Version")])
        return b""

    def _note_write(self, servo: SimServo, addr: int, size: int) -> None:
        names = [n for n, (a, k) in servo.table.items() if addr <= a and a + k <= addr + size]
        servo.last_write = ", ".join(f"{n}={servo.get_reg(n)}" for n in names) or f"{size} byte(s) at {addr}"
        servo.last_write_time = time.monotonic()

    def _handle_unchecked(self, motor_id: int, inst: int, params: bytes) -> None:
        dxl = self.vendor == "dynamixel"
        with self._lock:
            listening = self.on_bus(BROADCAST_ID)
            if inst == 0x82:  # SYNC_READ
                if dxl:
                    addr, size, ids = params[0] | params[1] << 8, params[2] | params[3] << 8, params[4:]
                else:
                    addr, size, ids = params[0], params[1], params[2:]
                for i in ids:
                    for servo in listening:
                        if servo.bus_id == i and i not in self.silent_ids:
                            self._send(self._status(i, 0, self._read(servo, addr, size)))
                return
            if inst == 0x83:  # SYNC_WRITE
                if dxl:
                    addr, size, rest = params[0] | params[1] << 8, params[2] | params[3] << 8, params[4:]
                else:
                    addr, size, rest = params[0], params[1], params[2:]
                for k in range(0, len(rest) - size + 1 if size else 0, size + 1):
                    for servo in [s for s in listening if s.bus_id == rest[k]]:
                        if not self._write(servo, addr, rest[k + 1 : k + 1 + size]):
                            self._note_write(servo, addr, size)
                return
            if motor_id == BROADCAST_ID:
                if inst == 0x01:  # every servo answers a broadcast PING, lowest id first
                    for servo in sorted(listening, key=lambda s: s.bus_id):
                        if servo.bus_id not in self.silent_ids:
                            self._send(self._status(servo.bus_id, 0, self._ping_params(servo)))
                elif inst == 0x03:  # broadcast WRITE: applied by all, answered by none
                    addr, data = (params[0] | params[1] << 8, params[2:]) if dxl else (params[0], params[1:])
                    for servo in listening:
                        if not self._write(servo, addr, data):
                            self._note_write(servo, addr, len(data))
                return
            targets = [s for s in listening if s.bus_id == motor_id]
            if not targets or motor_id in self.silent_ids:
                return
            for servo in targets:  # two servos sharing an id both answer (and collide), as on hardware
                if inst == 0x01:  # PING
                    self._send(self._status(motor_id, 0, self._ping_params(servo)))
                elif inst == 0x02:  # READ
                    if dxl:
                        addr, size = params[0] | params[1] << 8, params[2] | params[3] << 8
                    else:
                        addr, size = params[0], params[1]
                    self._send(self._status(motor_id, 0, self._read(servo, addr, size)))
                elif inst == 0x03:  # WRITE: acknowledged with the old id at the old speed, then applied
                    addr, data = (params[0] | params[1] << 8, params[2:]) if dxl else (params[0], params[1:])
                    error = self._write(servo, addr, data)
                    if not error:
                        self._note_write(servo, addr, len(data))
                    self._send(self._status(motor_id, error))
                else:
                    self._send(self._status(motor_id, 2 if dxl else 0))

    # ------------------------------------------------------------------------------------- helpers
    def move(self, positions: Mapping[int, float]) -> None:
        """Move servos by hand: motor id → actual ticks (thread-safe)."""
        with self._lock:
            for i, pos in positions.items():
                self.servos[i].move_to(pos)

    def attach(self, slots: Iterable[int] | None) -> None:
        """Plug in exactly these servos (by the id they were built with); None plugs in every servo."""
        with self._lock:
            keep = set(self.servos) if slots is None else set(slots)
            unknown = keep - set(self.servos)
            if unknown:
                raise UsageError(f"no simulated servo {sorted(unknown)}; servos: {sorted(self.servos)}")
            for i, servo in self.servos.items():
                servo.attached = i in keep

    def snapshot(self) -> dict[int, dict[str, int]]:
        """EEPROM calibration registers of every servo."""
        with self._lock:
            return {i: s.eeprom_snapshot() for i, s in self.servos.items()}
