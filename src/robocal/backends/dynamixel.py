"""Dynamixel X servos (protocol 2.0, little-endian) via ``dynamixel_sdk``.

The SDK is imported lazily (``pip install 'robocal[dynamixel]'``). Signed registers are two's complement;
firmware ``Present = Actual + Homing_Offset``; ``Drive_Mode`` bit 0 reverses the direction in hardware.
"""

from __future__ import annotations

from collections.abc import Mapping

from ..core.lerobot import decode_twos_complement, encode_twos_complement
from ._servo_common import SdkBusBase, ServoModel

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

DYNAMIXEL_MODELS: dict[str, ServoModel] = {
    "xl330-m077": ServoModel(1190, 4096, 2, X_TABLE),
    "xl330-m288": ServoModel(1200, 4096, 2, X_TABLE),
    "xl430-w250": ServoModel(1060, 4096, 2, X_TABLE),
    "xm430-w350": ServoModel(1020, 4096, 2, X_TABLE),
    "xm540-w270": ServoModel(1120, 4096, 2, X_TABLE),
    "xc430-w150": ServoModel(1070, 4096, 2, X_TABLE),
}
"""Model → its number, resolution, protocol (2.0) and control table (all X series)."""

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
    _sdk_module = "dynamixel_sdk"
    _models = DYNAMIXEL_MODELS

    def _protocol(self, motors: Mapping[int, str]) -> float:
        return 2.0

    def _encode(self, motor_id: int, register: str, value: int) -> int:
        if register in SIGNED_BYTES:
            return encode_twos_complement(value, SIGNED_BYTES[register])
        return int(value)

    def _decode(self, motor_id: int, register: str, raw: int) -> int:
        if register in SIGNED_BYTES:
            return decode_twos_complement(raw, SIGNED_BYTES[register])
        return int(raw)

    def reboot(self, motor_id: int) -> None:
        """REBOOT instruction (0x08): the only way to clear ``Hardware_Error_Status``; torque is off after it."""
        self._entry(motor_id, "Torque_Enable")

        def call() -> tuple[None, int, int]:
            result, error = self._ph.reboot(self._port_handler, motor_id)
            return None, result, error

        self._call("reboot", motor_id, "Torque_Enable", call)
