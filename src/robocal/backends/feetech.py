"""Feetech STS/SMS (protocol 0, little-endian) and SCS (protocol 1, big-endian) servos via ``scservo_sdk``.

The SDK is imported lazily (``pip install 'robocal[feetech]'``). Homing_Offset is sign-magnitude with the sign
at bit 11, positions and speeds at bit 15, load at bit 10; firmware ``Present = Actual − Homing_Offset``.
Note: ``scservo_sdk`` keeps the byte order in a module global, so one process talks to one Feetech protocol.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

from ..core.lerobot import decode_sign_magnitude, encode_sign_magnitude
from ..errors import DeviceError, UsageError
from . import require
from ._servo_common import COMM_SUCCESS, SdkBusBase

__all__ = ["FEETECH_MODELS", "SCS_TABLE", "SIGN_BITS", "STS_TABLE", "FeetechBus"]

STS_TABLE: dict[str, tuple[int, int]] = {
    "Firmware_Major_Version": (0, 1),
    "Firmware_Minor_Version": (1, 1),
    "Model_Number": (3, 2),
    "ID": (5, 1),
    "Baud_Rate": (6, 1),
    "Return_Delay_Time": (7, 1),
    "Response_Status_Level": (8, 1),
    "Min_Position_Limit": (9, 2),
    "Max_Position_Limit": (11, 2),
    "Max_Temperature_Limit": (13, 1),
    "Max_Voltage_Limit": (14, 1),
    "Min_Voltage_Limit": (15, 1),
    "Max_Torque_Limit": (16, 2),
    "Phase": (18, 1),
    "Unloading_Condition": (19, 1),
    "LED_Alarm_Condition": (20, 1),
    "P_Coefficient": (21, 1),
    "D_Coefficient": (22, 1),
    "I_Coefficient": (23, 1),
    "Minimum_Startup_Force": (24, 2),
    "CW_Dead_Zone": (26, 1),
    "CCW_Dead_Zone": (27, 1),
    "Protection_Current": (28, 2),
    "Angular_Resolution": (30, 1),
    "Homing_Offset": (31, 2),
    "Operating_Mode": (33, 1),
    "Protective_Torque": (34, 1),
    "Protection_Time": (35, 1),
    "Overload_Torque": (36, 1),
    "Torque_Enable": (40, 1),
    "Acceleration": (41, 1),
    "Goal_Position": (42, 2),
    "Goal_Time": (44, 2),
    "Goal_Velocity": (46, 2),
    "Torque_Limit": (48, 2),
    "Lock": (55, 1),
    "Present_Position": (56, 2),
    "Present_Velocity": (58, 2),
    "Present_Load": (60, 2),
    "Present_Voltage": (62, 1),
    "Present_Temperature": (63, 1),
    "Status": (65, 1),
    "Moving": (66, 1),
    "Present_Current": (69, 2),
    "Maximum_Acceleration": (85, 1),
}
"""STS3215 (and STS/SMS series) control table: name → (address, bytes)."""

SCS_TABLE: dict[str, tuple[int, int]] = {
    "Model_Number": (3, 2),
    "ID": (5, 1),
    "Baud_Rate": (6, 1),
    "Return_Delay_Time": (7, 1),
    "Min_Position_Limit": (9, 2),
    "Max_Position_Limit": (11, 2),
    "Torque_Enable": (40, 1),
    "Acceleration": (41, 1),
    "Goal_Position": (42, 2),
    "Goal_Time": (44, 2),
    "Goal_Speed": (46, 2),
    "Lock": (48, 1),
    "Present_Position": (56, 2),
    "Present_Speed": (58, 2),
    "Present_Load": (60, 2),
    "Present_Voltage": (62, 1),
    "Present_Temperature": (63, 1),
    "Moving": (66, 1),
}
"""SCS0009 control table (protocol 1, no Homing_Offset)."""

FEETECH_MODELS: dict[str, tuple[int, int, int, dict[str, tuple[int, int]]]] = {
    "sts3215": (777, 4096, 0, STS_TABLE),
    "sts3250": (2825, 4096, 0, STS_TABLE),
    "sm8512bl": (11272, 4096, 0, STS_TABLE),
    "scs0009": (1284, 1024, 1, SCS_TABLE),
}
"""Model → (model number, resolution, protocol, control table)."""

SIGN_BITS: dict[str, int] = {
    "Homing_Offset": 11,
    "Goal_Position": 15,
    "Goal_Velocity": 15,
    "Goal_Speed": 15,
    "Present_Position": 15,
    "Present_Velocity": 15,
    "Present_Speed": 15,
    "Present_Load": 10,
}
"""STS/SMS sign-magnitude sign bit per register (scs0009: none)."""


class FeetechBus(SdkBusBase):
    """A Feetech bus on a serial port through the unmodified ``scservo_sdk``.

    Args:
        port: Serial device (``/dev/ttyACM0``) or a simulator's pseudo-terminal.
        motors: Motor id → model (``"sts3215"``, ``"scs0009"``, ...). All on one protocol.
        baudrate: Bus speed, default 1 Mbit/s.
        retries: Extra attempts after a failed transfer (LeRobot legacy: 20; current sync reads: 5).
        packet_timeout_ms: Minimum wait for a status packet (the SDK's own is ~34 ms at 1 Mbit/s); None keeps
            the SDK's.

    Raises:
        BackendNotAvailableError: ``scservo_sdk`` is not installed.
        DeviceError: The port cannot be opened (exit 3).
    """

    vendor = "feetech"

    def __init__(
        self,
        port: str,
        motors: Mapping[int, str],
        *,
        baudrate: int = 1_000_000,
        retries: int = 3,
        packet_timeout_ms: float | None = 100.0,
    ) -> None:
        sdk = require("scservo_sdk", "the Feetech backend")
        unknown = sorted({m for m in motors.values() if m not in FEETECH_MODELS})
        if unknown:
            raise UsageError(
                f"unknown Feetech model(s) {', '.join(unknown)}; known: {', '.join(FEETECH_MODELS)}"
            )
        protocols = {FEETECH_MODELS[m][2] for m in motors.values()}
        if len(protocols) != 1:
            raise UsageError("Feetech motors of protocol 0 (STS/SMS) and 1 (SCS) cannot share one bus object")
        self.protocol = protocols.pop()
        self.port = port
        self.motors = dict(motors)
        self.retries = retries
        self._tables = {m: FEETECH_MODELS[m][3] for m in FEETECH_MODELS}
        self._sdk = sdk
        self._port_handler = sdk.PortHandler(port)
        self._ph = sdk.PacketHandler(self.protocol)
        try:
            ok = self._port_handler.openPort() and self._port_handler.setBaudRate(baudrate)
        except Exception as exc:  # pyserial raises SerialException (an OSError) or ValueError
            raise DeviceError(f"{port}: cannot open the serial port ({exc})") from None
        if not ok:
            raise DeviceError(f"{port}: cannot open the serial port at {baudrate} baud")
        self._install_timeout(packet_timeout_ms)

    def resolution(self, motor_id: int) -> int:
        """Ticks per turn of that motor's model."""
        return FEETECH_MODELS[self.motors[motor_id]][1]

    def _encode(self, motor_id: int, register: str, value: int) -> int:
        if self.protocol == 0 and register in SIGN_BITS:
            return encode_sign_magnitude(value, SIGN_BITS[register])
        return int(value)

    def _decode(self, motor_id: int, register: str, raw: int) -> int:
        if self.protocol == 0 and register in SIGN_BITS:
            return decode_sign_magnitude(raw, SIGN_BITS[register])
        return int(raw)

    def _select_protocol(self) -> None:
        self._sdk.scservo_def.SCS_SETEND(self.protocol)

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
        fn = {
            1: self._ph.read1ByteTxRx,
            2: self._ph.read2ByteTxRx,
            4: self._ph.read4ByteTxRx,
        }[size]
        raw = self._call("read", motor_id, register, lambda: fn(self._port_handler, motor_id, addr))
        return self._decode(motor_id, register, int(raw))

    def write(self, register: str, motor_id: int, value: int) -> None:
        """Encode and write one register of one motor, waiting for its status packet."""
        addr, size = self._entry(motor_id, register)
        data = self._encode(motor_id, register, value)
        if not 0 <= data < (1 << (8 * size)):
            raise UsageError(
                f"{self.port}: motor {motor_id}: value {value} does not fit register {register!r}"
            )
        self._select_protocol()
        fn = {1: self._ph.write1ByteTxRx, 2: self._ph.write2ByteTxRx, 4: self._ph.write4ByteTxRx}[size]

        def call() -> tuple[Any, int, int]:
            result, error = fn(self._port_handler, motor_id, addr, data)
            return None, result, error

        self._call("write", motor_id, register, call)

    def sync_read(self, register: str, motor_ids: Sequence[int]) -> dict[int, int]:
        """Read one register of several motors with one SYNC_READ instruction."""
        entries = {self._entry(i, register) for i in motor_ids}
        if len(entries) != 1:
            raise UsageError(
                f"{self.port}: register {register!r} differs between the models of {list(motor_ids)}"
            )
        addr, size = entries.pop()
        self._select_protocol()
        group = self._sdk.GroupSyncRead(self._port_handler, self._ph, addr, size)
        for i in motor_ids:
            group.addParam(i)

        def call() -> tuple[Any, int, int]:
            result = group.txRxPacket()
            if result != COMM_SUCCESS:
                return None, result, 0
            for i in motor_ids:
                if not group.isAvailable(i, addr, size):
                    return None, self._sdk.COMM_RX_CORRUPT, 0
            return {i: int(group.getData(i, addr, size)) for i in motor_ids}, result, 0

        raw = self._call("sync read", None, register, call)
        return {i: self._decode(i, register, v) for i, v in raw.items()}

    def sync_write(self, register: str, values: Mapping[int, int]) -> None:
        """Write one register of several motors with one SYNC_WRITE instruction."""
        entries = {self._entry(i, register) for i in values}
        if len(entries) != 1:
            raise UsageError(
                f"{self.port}: register {register!r} differs between the models of {list(values)}"
            )
        addr, size = entries.pop()
        self._select_protocol()
        group = self._sdk.GroupSyncWrite(self._port_handler, self._ph, addr, size)
        for i, v in values.items():
            data = self._encode(i, register, v)
            group.addParam(
                i,
                [(data >> (8 * k)) & 0xFF for k in range(size)]
                if self.protocol == 0
                else [(data >> (8 * (size - 1 - k))) & 0xFF for k in range(size)],
            )

        def call() -> tuple[Any, int, int]:
            return None, group.txPacket(), 0

        self._call("sync write", None, register, call)

    def close(self) -> None:
        """Close the port."""
        if self._port_handler.is_open:
            self._port_handler.closePort()

    def __enter__(self) -> FeetechBus:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
