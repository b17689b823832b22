"""Shared machinery of the vendor-SDK servo buses.

Port opening, register access, sync transfers, retries and error mapping. :class:`FeetechBus` and
:class:`DynamixelBus` only add their control tables and sign encodings.
"""

from __future__ import annotations

import contextlib
import select
from collections.abc import Callable, Mapping, Sequence
from typing import Any, NamedTuple

from ..core.lifecycle import ClosesOnExit
from ..errors import CalibTimeoutError, DeviceError, DeviceGoneError, ProtocolError, UsageError
from . import inproc_serial, reply_timeout_floor_s, require
from .bus_transaction import transaction

try:  # pyserial raises termios.error (not an OSError) when a USB adapter vanishes under tcflush/tcgetattr
    from termios import error as _TERMIOS_ERROR  # noqa: N812
except ImportError:  # pragma: no cover - Windows
    _TERMIOS_ERROR = OSError  # type: ignore[misc,assignment]

__all__ = ["SdkBusBase", "ServoModel"]

COMM_SUCCESS = 0

IDLE_WAIT_S = 0.001
"""How long a read that finds no reply byte waiting blocks on the port (``select``) before the SDK looks again.

The SDKs open the port with ``timeout=0`` and spin on ``read`` until the reply or their packet timeout: a core at
100 % per waiting bus, and in one process (a simulator's thread answering a pseudo-terminal) the spinning thread
holds the interpreter lock the answering one needs. The wait ends at the first byte, so no reply is later."""


class ServoModel(NamedTuple):
    """What robocal knows about one servo model (a row of a vendor's model table)."""

    model_number: int
    """What the ``Model_Number`` register reads."""
    resolution: int
    """Encoder ticks per turn."""
    protocol: int
    """Wire protocol: Feetech 0 (STS/SMS, little-endian, sign-magnitude) or 1 (SCS, big-endian); Dynamixel 2."""
    table: Mapping[str, tuple[int, int]]
    """Control table: register name → (address, bytes)."""


class SdkBusBase(ClosesOnExit):
    """Everything :class:`FeetechBus` and :class:`DynamixelBus` share; subclasses set the tables and codecs.

    Subclass hooks: ``_models`` (model name → :class:`ServoModel`), ``_encode`` / ``_decode`` (sign
    encodings), ``_select_protocol`` (called before every transfer), ``_big_endian`` (byte order of SYNC_WRITE
    data).
    """

    vendor = ""
    port: str
    label: str
    """How messages name the port: ``port``, or what the user gave for a simulated arm (``sim``)."""
    motors: Mapping[int, str]
    retries: int
    _big_endian = False
    _ph: Any
    _sdk: Any
    _port_handler: Any

    # ------------------------------------------------------------------------------------------- set-up
    _sdk_module = ""
    """Import name of the vendor SDK (``scservo_sdk`` / ``dynamixel_sdk``)."""
    _models: Mapping[str, ServoModel] = {}
    """The vendor's models: name → :class:`ServoModel`."""

    def __init__(
        self,
        port: str,
        motors: Mapping[int, str],
        *,
        baudrate: int = 1_000_000,
        retries: int = 3,
        packet_timeout_ms: float | None = 100.0,
        label: str | None = None,
    ) -> None:
        """Check the models, open ``port`` through the SDK and install the packet timeout.

        ``label`` is how messages name the port (default ``port``): ``sim`` for a simulated arm, whose
        pseudo-terminal or in-process name the user never gave.

        Raises:
            BackendNotAvailableError: The vendor SDK is not installed.
            UsageError: An unknown model (or, on Feetech, mixed protocols).
            DeviceError: The port cannot be opened (exit 3).
        """
        sdk = require(self._sdk_module, f"the {self.vendor.capitalize()} backend")
        protocol = self._protocol(motors)
        unknown = sorted({m for m in motors.values() if m not in self._models})
        if unknown:
            raise UsageError(
                f"unknown {self.vendor.capitalize()} model(s) {', '.join(unknown)}; "
                f"known: {', '.join(self._models)}"
            )
        self.port = port
        self.label = port if label is None else label
        self.motors = dict(motors)
        self.retries = retries
        self.watchdog_armed_s: dict[int, float] = {}
        """Motor id → the host-loss watchdog time armed on it (s); empty where none is armed or the family has
        none (Feetech). The joint drivers check a motor whose host was silent long enough to trip it."""
        self._sdk = sdk
        self._port_handler = sdk.PortHandler(port)
        self._ph = sdk.PacketHandler(protocol)
        if port.startswith(inproc_serial.PREFIX):
            self._install_in_process(port)
        try:
            ok = self._port_handler.openPort() and self._port_handler.setBaudRate(baudrate)
        except Exception as exc:  # pyserial raises SerialException (an OSError) or ValueError
            raise DeviceError(f"{self.label}: cannot open the serial port ({exc})") from None
        if not ok:
            raise DeviceError(f"{self.label}: cannot open the serial port at {baudrate} baud")
        self._install_timeout(packet_timeout_ms)
        self._install_drain()
        if not port.startswith(inproc_serial.PREFIX):  # an in-process port never waits: its time is its own
            self._install_idle_wait()

    def _install_in_process(self, port: str) -> None:
        """Open an in-process port (:mod:`.inproc_serial`) where the SDK would open ``serial.Serial(port)``.

        Only the SDK's ``setupPort`` (which builds the pyserial object) and its clock (``getCurrentTime``, which
        times the reply timeouts) are replaced, on this port object only: every packet is still built, sent,
        read and checked by the SDK.

        Raises:
            DeviceError: No simulator answers that name (it was stopped, or never started).
        """
        opener = inproc_serial.lookup(port)
        if opener is None:
            raise DeviceError(f"{self.label}: no in-process port of that name (its simulator is not running)")
        handler = self._port_handler

        def setup_port(cflag_baud: int) -> bool:
            if handler.is_open:
                handler.closePort()
            handler.ser = opener(int(handler.baudrate))
            handler.is_open = True
            handler.ser.reset_input_buffer()
            handler.tx_time_per_byte = (1000.0 / handler.baudrate) * 10.0
            return True

        def current_time_ms() -> float:
            ser = handler.ser
            return float(ser.now_ms()) if ser is not None else 0.0

        handler.setupPort = setup_port
        handler.getCurrentTime = current_time_ms

    def _install_drain(self) -> None:
        """Drop late replies before each packet the SDK sends (on this port object only).

        The SDKs' ``clearPort`` (called before every transmission) only flushes the output: a status packet that
        arrived after its read timed out would be taken as the reply to the next read, whatever its length (a
        block read's first byte as a one-byte register). Emptying the input first makes a late reply harmless.
        """
        handler = self._port_handler
        original = handler.clearPort

        def clear_port() -> None:
            ser = getattr(handler, "ser", None)
            if ser is not None:
                with contextlib.suppress(Exception):  # a port that cannot be drained is left to the SDK as it was
                    ser.reset_input_buffer()
            original()

        handler.clearPort = clear_port

    def _install_idle_wait(self) -> None:
        """Before each SDK read, block up to :data:`IDLE_WAIT_S` on the port while no byte is waiting.

        On this port object only. The bytes read, and the SDK's timeouts (measured on its clock after each read),
        are the same.
        """
        handler = self._port_handler
        original = handler.readPort

        def read_port(length: int) -> Any:
            ser = getattr(handler, "ser", None)
            with contextlib.suppress(Exception):  # a port that cannot be waited on is read as before
                if ser is not None and not ser.in_waiting:
                    select.select([ser.fileno()], [], [], IDLE_WAIT_S)
            return original(length)

        handler.readPort = read_port

    def _protocol(self, motors: Mapping[int, str]) -> float:
        """The SDK's PacketHandler protocol version for these motors."""
        raise NotImplementedError

    def _install_timeout(self, packet_timeout_ms: float | None) -> None:
        """Raise the SDK's per-packet timeout to at least ``packet_timeout_ms`` (on this port object only).

        And to at least ``$ROBOCAL_REPLY_TIMEOUT_MS`` (:func:`robocal.backends.reply_timeout_floor_s`).
        """
        floor_ms = reply_timeout_floor_s() * 1000.0
        if floor_ms > 0:
            packet_timeout_ms = max(packet_timeout_ms or 0.0, floor_ms)
        if packet_timeout_ms is None:
            return
        handler = self._port_handler
        original = handler.setPacketTimeout

        def set_packet_timeout(packet_length: int) -> None:
            original(packet_length)
            handler.packet_timeout = max(handler.packet_timeout, float(packet_timeout_ms))

        handler.setPacketTimeout = set_packet_timeout

    # ------------------------------------------------------------------------------------ subclass hooks
    def _encode(self, motor_id: int, register: str, value: int) -> int:
        """Register value → unsigned wire value (sign encoding)."""
        return int(value)

    def _decode(self, motor_id: int, register: str, raw: int) -> int:
        """Unsigned wire value → register value."""
        return int(raw)

    def _select_protocol(self) -> None:
        """Called before every transfer (Feetech: the SDK's global byte order)."""

    # ------------------------------------------------------------------------------------------ helpers
    def _entry(self, motor_id: int, register: str) -> tuple[int, int]:
        if motor_id not in self.motors:
            raise UsageError(
                f"{self.label}: motor id {motor_id} is not on this bus (ids {sorted(self.motors)})"
            )
        table = self._models[self.motors[motor_id]].table
        if register not in table:
            raise UsageError(
                f"{self.label}: motor {motor_id} ({self.motors[motor_id]}) has no register {register!r}"
            )
        return table[register]

    def _shared_entry(self, motor_ids: Sequence[int], register: str) -> tuple[int, int]:
        """The (address, size) of ``register``, which must be the same on every motor of a sync transfer."""
        if not motor_ids:
            raise UsageError(f"{self.label}: sync transfer of {register!r} with no motor ids")
        entries = {self._entry(i, register) for i in motor_ids}
        if len(entries) != 1:
            raise UsageError(
                f"{self.label}: register {register!r} differs between the models of {list(motor_ids)}"
            )
        return entries.pop()

    def _wire_value(self, motor_id: int, register: str, value: int, size: int) -> int:
        """Encoded value, checked to fit the register (before anything is sent)."""
        data = self._encode(motor_id, register, value)
        if not 0 <= data < (1 << (8 * size)):
            raise UsageError(
                f"{self.label}: motor {motor_id}: value {value} does not fit register {register!r}"
            )
        return data

    def _drain(self) -> None:
        """Drop late bytes of a failed transfer so a retry cannot read a stale status packet."""
        ser = getattr(self._port_handler, "ser", None)
        if ser is not None:
            with contextlib.suppress(Exception):
                ser.reset_input_buffer()

    def _call(
        self, what: str, motor_id: int | None, register: str, fn: Callable[[], tuple[Any, int, int]]
    ) -> Any:
        """Run an SDK call with retries; map failures to DeviceError / CalibTimeoutError / ProtocolError."""
        result, error, value = COMM_SUCCESS, 0, None
        who = f"motor {motor_id}" if motor_id is not None else "motors"
        garbled = ""
        for attempt in range(self.retries + 1):
            if attempt:
                self._drain()
            garbled = ""
            try:
                with transaction():  # a signal's exception comes out after the exchange, never inside it
                    self._port_handler.is_using = False  # a packet cut short (other thread) left it set
                    value, result, error = fn()
            except (OSError, _TERMIOS_ERROR) as exc:  # SerialException, EIO, termios.error: the port went away
                raise DeviceGoneError(
                    f"{self.label}: {who}: {what} {register!r} failed: the device is gone or not answering ({exc})"
                ) from None
            except (IndexError, KeyError, ValueError, TypeError, ZeroDivisionError) as exc:
                # the SDK indexes into a status packet it did not check (e.g. a stray short reply
                # answering a read): a garbled packet, retried like a bad checksum
                value, result, error = None, self._sdk.COMM_RX_CORRUPT, 0
                garbled = f" (garbled status packet: {type(exc).__name__}: {exc})"
            if result == COMM_SUCCESS and error == 0:
                return value
            if result == COMM_SUCCESS:
                break  # the motor answered with an error status: retrying will not help
        if result == COMM_SUCCESS:
            raise DeviceError(
                f"{self.label}: {who}: {what} {register!r} failed: {self._ph.getRxPacketError(error)}"
            )
        text = self._ph.getTxRxResult(result)
        msg = (
            f"{self.label}: {who}: {what} {register!r} failed after {self.retries + 1} tries: {text}{garbled}"
        )
        if result == self._sdk.COMM_RX_TIMEOUT:
            raise CalibTimeoutError(msg)
        if result == self._sdk.COMM_RX_CORRUPT:
            raise ProtocolError(msg)
        raise DeviceError(msg)

    # --------------------------------------------------------------------------------------- public API
    def resolution(self, motor_id: int) -> int:
        """Ticks per turn of that motor's model."""
        if motor_id not in self.motors:
            raise UsageError(
                f"{self.label}: motor id {motor_id} is not on this bus (ids {sorted(self.motors)})"
            )
        return self._models[self.motors[motor_id]].resolution

    def has_register(self, motor_id: int, register: str) -> bool:
        """Whether that motor's control table has the register."""
        return motor_id in self.motors and register in self._models[self.motors[motor_id]].table

    def check_write(self, register: str, motor_id: int, value: int) -> None:
        """Raise what :meth:`write` would raise for this value, without sending anything.

        Raises:
            UsageError: Unknown motor or register, or the value does not fit the register.
            InvalidCalibrationError: The sign encoding cannot hold the value.
        """
        self._wire_value(motor_id, register, value, self._entry(motor_id, register)[1])

    def ping(self, motor_id: int) -> int:
        """Model number reported by the motor."""
        self._select_protocol()
        return int(
            self._call("ping", motor_id, "Model_Number", lambda: self._ph.ping(self._port_handler, motor_id))
        )

    def read(self, register: str, motor_id: int) -> int:
        """Read and decode one register of one motor."""
        addr, size = self._entry(motor_id, register)
        self._select_protocol()
        fn = {1: self._ph.read1ByteTxRx, 2: self._ph.read2ByteTxRx, 4: self._ph.read4ByteTxRx}[size]
        raw = self._call("read", motor_id, register, lambda: fn(self._port_handler, motor_id, addr))
        return self._decode(motor_id, register, int(raw))

    def write(self, register: str, motor_id: int, value: int) -> None:
        """Encode and write one register of one motor, waiting for its status packet."""
        addr, size = self._entry(motor_id, register)
        data = self._wire_value(motor_id, register, value, size)
        self._select_protocol()
        fn = {1: self._ph.write1ByteTxRx, 2: self._ph.write2ByteTxRx, 4: self._ph.write4ByteTxRx}[size]

        def call() -> tuple[Any, int, int]:
            result, error = fn(self._port_handler, motor_id, addr, data)
            return None, result, error

        self._call("write", motor_id, register, call)

    def sync_read(self, register: str, motor_ids: Sequence[int]) -> dict[int, int]:
        """Read one register of several motors with one SYNC_READ instruction."""
        return {i: values[register] for i, values in self.sync_read_block([register], motor_ids).items()}

    def sync_read_block(self, registers: Sequence[str], motor_ids: Sequence[int]) -> dict[int, dict[str, int]]:
        """Read several registers of several motors with one SYNC_READ of the address span that holds them all.

        The span runs from the lowest register's address to the end of the highest one (e.g. Feetech
        Present_Position … Status, 10 bytes): one instruction instead of one per register.

        Returns:
            Motor id → register → decoded value.
        """
        entries = {r: self._shared_entry(motor_ids, r) for r in registers}
        start = min(a for a, _ in entries.values())
        length = max(a + k for a, k in entries.values()) - start
        self._select_protocol()
        group = self._sdk.GroupSyncRead(self._port_handler, self._ph, start, length)
        for i in motor_ids:
            group.addParam(i)

        def call() -> tuple[Any, int, int]:
            result = group.txRxPacket()
            if result != COMM_SUCCESS:
                return None, result, 0
            for i in motor_ids:
                if not group.isAvailable(i, start, length):
                    return None, self._sdk.COMM_RX_CORRUPT, 0
            return (
                {i: {r: int(group.getData(i, a, k)) for r, (a, k) in entries.items()} for i in motor_ids},
                result,
                0,
            )

        raw = self._call("sync read", None, "+".join(registers), call)
        return {i: {r: self._decode(i, r, v) for r, v in values.items()} for i, values in raw.items()}

    def sync_write(self, register: str, values: Mapping[int, int]) -> None:
        """Write one register of several motors with one SYNC_WRITE instruction (no status packets)."""
        addr, size = self._shared_entry(list(values), register)
        data = {i: self._wire_value(i, register, v, size) for i, v in values.items()}
        order = range(size - 1, -1, -1) if self._big_endian else range(size)
        self._select_protocol()
        group = self._sdk.GroupSyncWrite(self._port_handler, self._ph, addr, size)
        for i, d in data.items():
            group.addParam(i, [(d >> (8 * k)) & 0xFF for k in order])

        def call() -> tuple[Any, int, int]:
            return None, group.txPacket(), 0

        self._call("sync write", None, register, call)

    def close(self) -> None:
        """Close the port (a device that is gone is closed as far as it can be; never raises)."""
        if self._port_handler.is_open:
            with contextlib.suppress(Exception):
                self._port_handler.closePort()
            self._port_handler.is_open = False
