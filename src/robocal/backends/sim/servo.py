"""Simulated Feetech and Dynamixel servos answering real packets on a pseudo-terminal (or in process).

A :class:`SimServoBus` opens a pty (``os.openpty()``, raw mode) and runs one thread that parses instruction
packets written by the unmodified vendor SDK (Feetech protocol 0/1 with checksum; Dynamixel protocol 2.0 with
CRC-16 and byte stuffing; :mod:`.servo_packets`) and answers with status packets. Each
:class:`~.servo_model.SimServo` has a control table (bytes), a physical position in ticks (continuous,
multi-turn) limited by hard stops, optional read noise, and the firmware's homing semantics
(:mod:`.servo_model`).

Without physics a Goal_Position write with torque on places the shaft at once. A servo with a
:class:`~.servo_firmware.ServoFirmware` (a joint plant on the bus's :class:`~.physics.SimClock`) moves under
its firmware's control law instead: each packet advances the clock by ``latency_s`` and integrates every such
servo up to it; its status packets carry its fault bits; its replies are lost while the plant does not answer;
Dynamixel REBOOT (0x08) clears a hardware error.

Dynamixel EEPROM (addresses < 64) is read-only while torque is on (Access error); Feetech EEPROM writes are
refused with Lock = 1 only when ``enforce_lock`` is set. Registers start at the model's factory values
(:mod:`.servo_defaults`); a servo answers only what its status return level allows (Feetech
``Response_Status_Level`` 0: PING and READ); Feetech ``Torque_Enable`` 128 is "set middle" and ``Torque_Limit`` 0
means no torque (:meth:`SimServo.apply_set_middle`, :attr:`SimServo.drives`).

Bus behaviour as on hardware: a servo answers the id in its ``ID`` register (not the one it was built with),
only while it is plugged in (:attr:`SimServo.attached`) and only at its own baud rate (``Baud_Rate`` register).
A pty carries no baud rate, so the simulator reads the speed the client set on the terminal (``TCGETS2``) and
ignores packets sent at another speed. A write to ``ID`` or ``Baud_Rate`` is acknowledged with the old id at
the old speed, then takes effect. Broadcast PING (id 0xFE) is answered by every servo on the bus, in id order.

``transport="inproc"`` puts the same servos behind an in-process port (:mod:`robocal.backends.inproc_serial`,
``inproc://sim-servo-N``) instead: the SDK's ``write`` hands each packet's bytes to the same parser and servo
code in the caller's thread and its ``read`` returns the status packets (:mod:`.servo_inproc`); no pty, no thread.
The packets are the same byte for byte, and so is a seeded run (:attr:`SimServoBus.packet_log`).
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
from typing import TYPE_CHECKING

import numpy as np

from ...core.lifecycle import StartsOnEnter
from ...errors import UsageError
from .. import inproc_serial
from . import servo_watchdog
from .servo_group_reads import BULK_WRITE, GROUP_READS, bulk_write, group_read
from .servo_model import BAUD_RATES, BROADCAST_ID, SIM_SERVO_KINDS, SimServo, Vendor
from .servo_packets import dxl_crc16

if TYPE_CHECKING:
    from .physics import SimClock
    from .servo_inproc import InProcessSerial

__all__ = ["BAUD_RATES", "BROADCAST_ID", "SimServo", "SimServoBus", "dxl_crc16"]  # dxl_crc16: servo_packets

_SETTLE_MARK = b"\x00\xa5robocal-sim-settle\xa5\x00"
"""Written into the terminal by :meth:`SimServoBus.settle`; never part of a packet."""
_TCGETS2 = 0x802C542A  # _IOR('T', 0x2A, struct termios2) on x86 and the generic ioctl ABI (arm, arm64, riscv)
TRANSPORTS = ("pty", "inproc")
"""How a :class:`SimServoBus` is reached: a pseudo-terminal (a thread answers) or an in-process port."""


class SimServoBus(StartsOnEnter):
    """Servos of one vendor behind one pseudo-terminal, answered by a background thread.

    Args:
        servos: The servos on the bus (one vendor).
        noise_ticks: Uniform integer read noise ±``noise_ticks`` on Present_Position.
        seed: Seed of the noise generator.
        enforce_lock: Refuse Feetech EEPROM writes while Lock = 1 (status error bit 0x08).
        clock: Simulated time for servos with physics (:attr:`SimServo.firmware`): each packet advances it by
            ``latency_s`` and integrates every such servo up to it.
        latency_s: Simulated bus latency per packet.
        transport: ``"pty"`` (a pseudo-terminal answered by a thread) or ``"inproc"`` (an in-process port
            answered in the caller's thread: the same packets, no polling; for fast simulation).

    Use as a context manager; :attr:`port` is the name to hand to the SDK (a pty path or ``inproc://…``).
    """

    def __init__(
        self,
        servos: Sequence[SimServo],
        *,
        noise_ticks: int = 0,
        seed: int = 0,
        enforce_lock: bool = False,
        clock: SimClock | None = None,
        latency_s: float = 0.001,
        transport: str = "pty",
    ) -> None:
        if transport not in TRANSPORTS:
            raise UsageError(f"simulated servo bus transport {transport!r}: expected one of {', '.join(TRANSPORTS)}")
        self.transport = transport
        self.clock = clock
        self.latency_s = latency_s
        vendors = {s.vendor for s in servos}
        if len(vendors) != 1:
            raise UsageError("a simulated bus holds servos of exactly one vendor")
        self.vendor: Vendor = vendors.pop()
        self.kind = SIM_SERVO_KINDS[self.vendor]
        self.servos: dict[int, SimServo] = {s.motor_id: s for s in servos}
        self.noise_ticks = noise_ticks
        self.enforce_lock = enforce_lock
        self._rng = np.random.default_rng(seed)
        self._lock = threading.RLock()
        self._stop = threading.Event()
        self._client: InProcessSerial | None = None
        self._inbox = bytearray()
        if transport == "pty":
            self._master, self._slave = os.openpty()
            tty.setraw(self._master)
            tty.setraw(self._slave)
            self.port = os.ttyname(self._slave)
        else:
            self._master = self._slave = -1
            self.port = inproc_serial.new_name("sim-servo")
        self._thread = threading.Thread(target=self._run, name=f"sim-servo-{self.port}", daemon=True)
        self._settles: list[threading.Event] = []
        self.packet_log: list[tuple[str, bytes]] | None = None
        """Set to a list to record every packet: ``("rx", instruction bytes)`` / ``("tx", status bytes)``."""
        if clock is not None:
            clock.add_settler(self.settle)

        self.instructions = 0
        self.silent_ids: set[int] = set()
        """Ids that do not answer (to test timeouts)."""
        self.corrupt_next = 0
        """Number of upcoming status packets sent with a wrong checksum."""

    def use_clock(self, clock: SimClock) -> None:
        """Run on ``clock`` from now on (servos with physics are integrated to it)."""
        with self._lock:
            if self.clock is not None:
                self.clock.remove_settler(self.settle)
            self.clock = clock
            clock.add_settler(self.settle)

    # ------------------------------------------------------------------------------------ life cycle
    def start(self) -> SimServoBus:
        """Start answering packets (the pty's thread, or the in-process port's name)."""
        if self.transport == "inproc":
            inproc_serial.register(self.port, self._connect)
            return self
        self._thread.start()
        return self

    def stop(self) -> None:
        """Stop the thread (bounded wait) and close the pty (or unregister the in-process port)."""
        self._stop.set()
        if self.clock is not None:
            self.clock.remove_settler(self.settle)
        if self.transport == "inproc":
            inproc_serial.unregister(self.port)
            if self._client is not None:
                self._client.close()
            return
        if self._thread.is_alive():
            self._thread.join(timeout=2.0)
        for fd in (self._master, self._slave):
            with contextlib.suppress(OSError):
                os.close(fd)

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
                if self.clock is None:  # the watchdogs of a silent host, on the wall clock
                    with self._lock:
                        for servo in self.servos.values():
                            servo_watchdog.trip_if_due(servo, time.monotonic())
                continue
            try:
                chunk = os.read(self._master, 4096)
            except OSError:
                return
            buf.extend(chunk)
            while (mark := buf.find(_SETTLE_MARK)) >= 0:
                head = buf[:mark]
                self._parse_all(head)
                del buf[: mark + len(_SETTLE_MARK)]
                if self._settles:
                    self._settles.pop(0).set()
            self._parse_all(buf)

    def _connect(self, baudrate: int) -> InProcessSerial:
        """Open the in-process port at ``baudrate`` (the SDK's setupPort); a previous connection is closed."""
        from .servo_inproc import InProcessSerial

        with self._lock:
            if self._client is not None:
                self._client.close()
            self._inbox.clear()
            self._client = InProcessSerial(self, baudrate)
            return self._client

    def receive(self, data: bytes) -> None:
        """In-process transport: bytes the client wrote; every whole packet in them is answered at once."""
        with self._lock:
            self._inbox.extend(data)
            self._parse_all(self._inbox)

    def _parse_all(self, buf: bytearray) -> None:
        while True:
            consumed = self._parse(buf)
            if consumed == 0:
                return
            del buf[:consumed]

    def settle(self, timeout_s: float = 10.0) -> None:
        """Return once every packet the client has sent so far has been handled (for :meth:`SimClock.sleep`).

        A marker written into the same terminal after the client's packets is answered by the thread when it
        reaches it, so a write that gets no reply is applied before simulated time moves on.
        """
        if not self._thread.is_alive():
            return
        done = threading.Event()
        self._settles.append(done)
        try:
            os.write(self._slave, _SETTLE_MARK)
        except OSError:
            return
        done.wait(timeout_s)

    def _send(self, data: bytes) -> None:
        if self.packet_log is not None:
            self.packet_log.append(("tx", data))
        if self.transport == "inproc":
            if self._client is not None:
                self._client.deliver(data)
            return
        with contextlib.suppress(OSError):
            os.write(self._master, data)

    def _parse(self, buf: bytearray) -> int:
        """Handle one packet at the start of ``buf``; return bytes consumed (0 = need more)."""
        consumed, inst = self.kind.parse(buf)
        if inst is not None:
            if self.packet_log is not None:
                self.packet_log.append(("rx", bytes(buf[:consumed])))
            self.instructions += 1
            self._handle(*inst)
        return consumed

    # ------------------------------------------------------------------------------------- semantics
    def _status(self, motor_id: int, error: int, params: bytes = b"") -> bytes:
        corrupt = self.corrupt_next > 0
        self.corrupt_next -= int(corrupt)
        return self.kind.status(motor_id, error, params, corrupt=corrupt)

    def _reply(self, servo: SimServo, error: int, params: bytes = b"") -> None:
        """Send a status packet from ``servo`` (its firmware adds its fault bits; a silent plant sends nothing)."""
        fw = servo.firmware
        if fw is not None:
            if not fw.answers():
                return
            error |= fw.error_byte()
        self._send(self._status(servo.bus_id, error, params))

    def _reply_as(self, servo: SimServo, motor_id: int, error: int) -> None:
        """A write acknowledgement, sent with the id the servo had when the write arrived."""
        fw = servo.firmware
        if fw is not None:
            if not fw.answers():
                return
            error |= fw.error_byte()
        self._send(self._status(motor_id, error))

    def _tick(self) -> None:
        """Simulated time: one bus latency per packet; every servo with physics is integrated up to it."""
        if self.clock is None:
            return
        self.clock.advance(self.latency_s)
        for servo in self.servos.values():
            if servo.firmware is not None:
                servo_watchdog.trip_if_due(servo, self.clock.now())
                servo.firmware.sync()

    def _refresh(self, servo: SimServo) -> None:
        noise = int(self._rng.integers(-self.noise_ticks, self.noise_ticks + 1)) if self.noise_ticks else 0
        present = servo.present_ticks(noise)
        addr, size = servo.table["Present_Position"]
        servo.regs[addr : addr + size] = servo._pack(servo.encode_reading("Present_Position", present), size)
        if servo.firmware is not None:
            servo.firmware.refresh()
        else:
            servo.regs[servo.table["Moving"][0]] = 0

    def _read(self, servo: SimServo, addr: int, size: int) -> bytes:
        self._refresh(servo)
        pos, pos_size = servo.table["Present_Position"]
        if addr <= pos and pos + pos_size <= addr + size:
            servo.position_reads += 1
        return bytes(servo.regs[addr : addr + size])

    def _write(self, servo: SimServo, addr: int, data: bytes) -> int:
        """Apply a register write; return the status error byte."""
        if refused := servo_watchdog.write_error(servo, addr, data):
            return refused
        torque_addr = servo.table["Torque_Enable"][0]
        lock = servo.vendor_spec.lock_register
        if servo.kind.eeprom_locked_by_torque:
            if addr < torque_addr and servo.regs[torque_addr]:
                return 7  # Access error: EEPROM is locked while torque is on
        elif lock is not None:
            lock_addr = servo.table[lock][0]
            if self.enforce_lock and addr < torque_addr and servo.regs[lock_addr]:
                return 0x08
        if servo.out_of_range(addr, data) is not None:
            return servo.kind.range_error  # e.g. Max_Position_Limit 70000 (Dynamixel: Data Range error)
        data = servo.apply_set_middle(addr, data)  # Feetech Torque_Enable 128: Homing_Offset so Present reads 2048
        fw = servo.firmware
        if fw is not None:
            refused = fw.write_error(addr, data)
            if refused:
                return refused
            was_on = bool(servo.regs[torque_addr])
            servo.regs[addr : addr + len(data)] = data
            fw.after_write(addr, len(data), was_on)
            return 0
        servo.regs[addr : addr + len(data)] = data
        goal_addr, _goal_size = servo.table["Goal_Position"]
        if servo.drives and addr <= goal_addr < addr + len(data):  # Torque_Limit 0: no torque, no move
            servo.move_to(servo.goal_to_actual(servo.get_reg("Goal_Position")))
        return 0

    send, reply, read_registers, write_registers = _send, _reply, _read, _write  # for :mod:`.servo_group_reads`

    def client_baudrate(self) -> int | None:
        """Bit/s the client last set on the terminal (``TCGETS2``), or None where it cannot be read.

        In process: the baud rate the client opened the port at (None while it is not open).
        """
        if self.transport == "inproc":
            client = self._client
            return client.baudrate if client is not None and client.is_open else None
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
        if servo.kind.ping_reports_model:
            number = servo.get_reg("Model_Number")
            return bytes([number & 0xFF, number >> 8, servo.get_reg("Firmware_Version")])
        return b""

    def _note_write(self, servo: SimServo, addr: int, size: int) -> None:
        names = [n for n, (a, k) in servo.table.items() if addr <= a and a + k <= addr + size]
        servo.last_write = ", ".join(f"{n}={servo.get_reg(n)}" for n in names) or f"{size} byte(s) at {addr}"
        servo.last_write_time = time.monotonic()

    note_write = _note_write  # for :mod:`.servo_group_reads`

    def _handle_unchecked(self, motor_id: int, inst: int, params: bytes) -> None:
        wide = self.kind.address_bytes == 2  # Dynamixel 2.0: 2-byte addresses and lengths
        with self._lock:
            self._tick()
            now = self.clock.now() if self.clock is not None else time.monotonic()
            for servo in self.servos.values():  # a servo whose watchdog ran out before this packet has stopped
                servo_watchdog.trip_if_due(servo, now)
            listening = self.on_bus(BROADCAST_ID)
            servo_watchdog.heard(listening, now)
            if wide and inst in GROUP_READS:  # Dynamixel Bulk Read, Fast Sync Read, Fast Bulk Read
                group_read(self, inst, params, listening)
                return
            if wide and inst == BULK_WRITE and motor_id == BROADCAST_ID:
                bulk_write(self, params, listening)
                return
            if inst == 0x82:  # SYNC_READ
                if wide:
                    addr, size, ids = params[0] | params[1] << 8, params[2] | params[3] << 8, params[4:]
                else:
                    addr, size, ids = params[0], params[1], params[2:]
                for i in ids:
                    for servo in listening:
                        if servo.bus_id == i and i not in self.silent_ids:
                            self._reply(servo, 0, self._read(servo, addr, size))
                return
            if inst == 0x83:  # SYNC_WRITE
                if wide:
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
                            self._reply(servo, 0, self._ping_params(servo))
                elif inst == 0x03:  # broadcast WRITE: applied by all, answered by none
                    addr, data = (params[0] | params[1] << 8, params[2:]) if wide else (params[0], params[1:])
                    for servo in listening:
                        if not self._write(servo, addr, data):
                            self._note_write(servo, addr, len(data))
                return
            targets = [s for s in listening if s.bus_id == motor_id]
            if not targets or motor_id in self.silent_ids:
                return
            for servo in targets:  # two servos sharing an id both answer (and collide), as on hardware
                answer = servo.answers(inst)  # its status return level when the instruction arrives
                if inst == 0x01:  # PING
                    self._reply(servo, 0, self._ping_params(servo))
                elif inst == 0x02:  # READ
                    if wide:
                        addr, size = params[0] | params[1] << 8, params[2] | params[3] << 8
                    else:
                        addr, size = params[0], params[1]
                    data = self._read(servo, addr, size)
                    if answer:
                        self._reply(servo, 0, data)
                elif inst == 0x03:  # WRITE: acknowledged with the old id at the old speed, then applied
                    addr, data = (params[0] | params[1] << 8, params[2:]) if wide else (params[0], params[1:])
                    old_id = servo.bus_id
                    error = self._write(servo, addr, data)
                    if not error:
                        self._note_write(servo, addr, len(data))
                    if answer:
                        self._reply_as(servo, old_id, error)
                elif inst == 0x08 and self.kind.reboot:  # REBOOT: clears a hardware error, torque off
                    servo.set_reg("Hardware_Error_Status", 0)
                    servo.set_reg("Torque_Enable", 0)
                    if servo.firmware is not None:
                        servo.firmware.reboot()
                    if answer:
                        self._reply(servo, 0)
                elif answer:
                    self._reply(servo, self.kind.unknown_instruction_error)

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
