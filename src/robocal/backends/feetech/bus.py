"""Feetech STS/SMS (protocol 0, little-endian) and SCS (protocol 1, big-endian) servos via ``scservo_sdk``.

The SDK is imported lazily (``pip install 'robocal[feetech]'``). Homing_Offset is sign-magnitude with the sign
at bit 11, positions and speeds at bit 15, load at bit 10; firmware ``Present = Actual − Homing_Offset``.
Note: ``scservo_sdk`` keeps the byte order in a module global, so one process talks to one Feetech protocol.
"""

from __future__ import annotations

from collections.abc import Mapping

from ...core.lerobot import decode_sign_magnitude, encode_sign_magnitude
from ...errors import UsageError
from .._servo_common import SdkBusBase
from .tables import FEETECH_MODELS, SIGN_BITS

__all__ = ["FeetechBus"]


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
    _sdk_module = "scservo_sdk"
    _models = FEETECH_MODELS

    def _protocol(self, motors: Mapping[int, str]) -> float:
        protocols = {FEETECH_MODELS[m].protocol for m in motors.values() if m in FEETECH_MODELS}
        if len(protocols) > 1:
            raise UsageError("Feetech motors of protocol 0 (STS/SMS) and 1 (SCS) cannot share one bus object")
        self.protocol = protocols.pop() if protocols else 0
        self._big_endian = self.protocol == 1
        return self.protocol

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
