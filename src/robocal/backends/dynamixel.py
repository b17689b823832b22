"""Dynamixel X servos (protocol 2.0, little-endian) via ``dynamixel_sdk``.

The SDK is imported lazily (``pip install 'robocal[dynamixel]'``). Signed registers are two's complement;
firmware ``Present = Actual + Homing_Offset``; ``Drive_Mode`` bit 0 reverses the direction in hardware.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

from ..core.lerobot import decode_twos_complement, encode_twos_complement
from ..errors import DeviceError, UsageError
from . import require
from ._servo_common import COMM_SUCCESS, SdkBusBase

__all__ = ["DYNAMIXEL_MODELS", "SIGNED_BYTES", "X_TABLE", "DynamixelBus"]

X_TABLE: dict[str, tuple[int, int]] = {
    "Model_Number": (0, 2),
    "Model_Information": (2, 4),
    "Firmware_Version": (6, 1),
    "ID": (7, 1),
    "Baud_Rate": (8, 1),
    "Return_Delay_Time": (9, 1),
    "Drive_Mode": (10, 1),
    "Operating_Mode": (11, 1),
    "Secondary_ID": (12, 1),
    "Protocol_Type": (13, 1),
    "Homing_Offset": (20, 4),
    "Moving_Threshold": (24, 4),
    "Temperature_Limit": (31, 1),
    "Max_Voltage_Limit": (32, 2),
    "Min_Voltage_Limit": (34, 2),
    "PWM_Limit": (36, 2),
    "Current_Limit": (38, 2),
    "Acceleration_Limit": (40, 4),
    "Velocity_Limit": (44, 4),
    "Max_Position_Limit": (48, 4),
    "Min_Position_Limit": (52, 4),
    "Shutdown": (63, 1),
    "Torque_Enable": (64, 1),
    "LED": (65, 1),
    "Status_Return_Level": (68, 1),
    "Hardware_Error_Status": (70, 1),
    "Velocity_I_Gain": (76, 2),
    "Velocity_P_Gain": (78, 2),
    "Position_D_Gain": (80, 2),
    "Position_I_Gain": (82, 2),
    "Position_P_Gain": (84, 2),
    "Goal_PWM": (100, 2),
    "Goal_Current": (102, 2),
    "Goal_Velocity": (104, 4),
    "Profile_Acceleration": (108, 4),
    "Profile_Velocity": (112, 4),
    "Goal_Position": (116, 4),
    "Moving": (122, 1),
    "Present_PWM": (124, 2),
    "Present_Current": (126, 2),
    "Present_Velocity": (128, 4),
    "Present_Position": (132, 4),
    "Present_Input_Voltage": (144, 2),
    "Present_Temperature": (146, 1),
}
"""Dynamixel X series control table: name → (address, bytes)."""

DYNAMIXEL_MODELS: dict[str, tuple[int, int]] = {
    "xl330-m077": (1190, 4096),
    "xl330-m288": (1200, 4096),
    "xl430-w250": (1060, 4096),
    "xm430-w350": (1020, 4096),
    "xm540-w270": (1120, 4096),
    "xc430-w150": (1070, 4096),
}
"""Model → (model number, resolution)."""

SIGNED_BYTES: dict[str, int] = {
    "Homing_Offset": 4,
    "Goal_PWM": 2,
    "Goal_Current": 2,
    "Goal_Velocity": 4,
    "Goal_Position": 4,
    "Present_Position": 4,
    "Present_PWM": 2,
    "Present_Current": 2,
    "Present_Velocity": 4,
}
"""Two's-complement registers and their width."""


class DynamixelBus(SdkBusBase):
    """A Dynamixel protocol 2.0 bus through the unmodified ``dynamixel_sdk``.

    Args:
        port: Serial device or a simulator's pseudo-terminal.
        motors: Motor id → model (``"xl330-m288"``, ...).
        baudrate: Bus speed, default 1 Mbit/s.
        retries: Extra attempts after a failed transfer.
        packet_timeout_ms: Minimum wait for a status packet (the SDK's own is ~34 ms at 1 Mbit/s); None keeps
            the SDK's.

    Raises:
        BackendNotAvailableError: ``dynamixel_sdk`` is not installed.
        DeviceError: The port cannot be opened (exit 3).
    """

    vendor = "dynamixel"

    def __init__(
        self,
        port: str,
        motors: Mapping[int, str],
        *,
        baudrate: int = 1_000_000,
        retries: int = 3,
        packet_timeout_ms: float | None = 100.0,
    ) -> None:
        sdk = require("dynamixel_sdk", "the Dynamixel backend")
        unknown = sorted({m for m in motors.values() if m not in DYNAMIXEL_MODELS})
        if unknown:
            raise UsageError(
                f"unknown Dynamixel model(s) {', '.join(unknown)}; known: {', '.join(DYNAMIXEL_MODELS)}"
            )
        self.port = port
        self.motors = dict(motors)
        self.retries = retries
        self._tables = dict.fromkeys(DYNAMIXEL_MODELS, X_TABLE)
        self._sdk = sdk
        self._port_handler = sdk.PortHandler(port)
        self._ph = sdk.PacketHandler(2.0)
        try:
            ok = self._port_handler.openPort() and self._port_handler.setBaudRate(baudrate)
        except Exception as exc:
            raise DeviceError(f"{port}: cannot open the serial port ({exc})") from None
        if not ok:
            raise DeviceError(f"{port}: cannot open the serial port at {baudrate} baud")
        self._install_timeout(packet_timeout_ms)

    def resolution(self, motor_id: int) -> int:
        """Ticks per turn of that motor's model."""
        return DYNAMIXEL_MODELS[self.motors[motor_id]][1]

    @staticmethod
    def _encode(register: str, value: int, size: int) -> int:
        if register in SIGNED_BYTES:
            return encode_twos_complement(value, SIGNED_BYTES[register])
        return int(value)

    @staticmethod
    def _decode(register: str, raw: int) -> int:
        if register in SIGNED_BYTES:
            return decode_twos_complement(raw, SIGNED_BYTES[register])
        return int(raw)

    def ping(self, motor_id: int) -> int:
        """Model number reported by the motor."""
        return int(
            self._call("ping", motor_id, "Model_Number", lambda: self._ph.ping(self._port_handler, motor_id))
        )

    def read(self, register: str, motor_id: int) -> int:
        """Read and decode one register of one motor."""
        addr, size = self._entry(motor_id, register)
        fn = {1: self._ph.read1ByteTxRx, 2: self._ph.read2ByteTxRx, 4: self._ph.read4ByteTxRx}[size]
        raw = self._call("read", motor_id, register, lambda: fn(self._port_handler, motor_id, addr))
        return self._decode(register, int(raw))

    def write(self, register: str, motor_id: int, value: int) -> None:
        """Encode and write one register of one motor, waiting for its status packet."""
        addr, size = self._entry(motor_id, register)
        data = self._encode(register, value, size)
        if not 0 <= data < (1 << (8 * size)):
            raise UsageError(
                f"{self.port}: motor {motor_id}: value {value} does not fit register {register!r}"
            )
        fn = {1: self._ph.write1ByteTxRx, 2: self._ph.write2ByteTxRx, 4: self._ph.write4ByteTxRx}[size]

        def call() -> tuple[Any, int, int]:
            result, error = fn(self._port_handler, motor_id, addr, data)
            return None, result, error

        self._call("write", motor_id, register, call)

    def sync_read(self, register: str, motor_ids: Sequence[int]) -> dict[int, int]:
        """Read one register of several motors with one SYNC_READ instruction."""
        addr, size = self._entry(motor_ids[0], register)
        for i in motor_ids:
            self._entry(i, register)
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
        return {i: self._decode(register, v) for i, v in raw.items()}

    def sync_write(self, register: str, values: Mapping[int, int]) -> None:
        """Write one register of several motors with one SYNC_WRITE instruction."""
        ids = list(values)
        addr, size = self._entry(ids[0], register)
        group = self._sdk.GroupSyncWrite(self._port_handler, self._ph, addr, size)
        for i, v in values.items():
            self._entry(i, register)
            data = self._encode(register, v, size)
            group.addParam(i, [(data >> (8 * k)) & 0xFF for k in range(size)])

        def call() -> tuple[Any, int, int]:
            return None, group.txPacket(), 0

        self._call("sync write", None, register, call)

    def close(self) -> None:
        """Close the port."""
        if self._port_handler.is_open:
            self._port_handler.closePort()

    def __enter__(self) -> DynamixelBus:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
