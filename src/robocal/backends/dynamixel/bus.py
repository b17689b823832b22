"""Dynamixel X servos (protocol 2.0, little-endian) via ``dynamixel_sdk``.

The SDK is imported lazily (``pip install 'robocal[dynamixel]'``). Signed registers are two's complement;
firmware ``Present = Actual + Homing_Offset``; ``Drive_Mode`` bit 0 reverses the direction in hardware.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

from ...core.lerobot import decode_twos_complement, encode_twos_complement
from .._servo_common import SdkBusBase
from .tables import BUS_WATCHDOG_UNIT_S, DYNAMIXEL_MODELS, SIGNED_BYTES

__all__ = ["DynamixelBus"]


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

    def arm_watchdog(self, motor_ids: Sequence[int], timeout_s: float) -> None:
        """Arm the host-loss watchdog (``Bus_Watchdog``, RAM) of each motor, checked with a status packet.

        With torque on and no instruction packet for ``timeout_s`` (20 ms units, at most 2.54 s) the motor stops
        on its own and refuses goal writes until :meth:`disarm_watchdog`.
        """
        units = max(1, min(127, round(timeout_s / BUS_WATCHDOG_UNIT_S)))
        for motor_id in motor_ids:
            self.write("Bus_Watchdog", motor_id, units)
            self.watchdog_armed_s[motor_id] = units * BUS_WATCHDOG_UNIT_S

    def disarm_watchdog(self, motor_ids: Sequence[int]) -> None:
        """``Bus_Watchdog`` 0 on each motor (off, and a tripped watchdog's error cleared); one SYNC_WRITE."""
        self.sync_write("Bus_Watchdog", dict.fromkeys(motor_ids, 0))
        for motor_id in motor_ids:
            self.watchdog_armed_s.pop(motor_id, None)

    def reboot(self, motor_id: int) -> None:
        """REBOOT instruction (0x08): the only way to clear ``Hardware_Error_Status``; torque is off after it."""
        self._entry(motor_id, "Torque_Enable")

        def call() -> tuple[None, int, int]:
            result, error = self._ph.reboot(self._port_handler, motor_id)
            return None, result, error

        self._call("reboot", motor_id, "Torque_Enable", call)
