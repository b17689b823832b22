"""Shared machinery of the vendor-SDK servo buses: retries and error mapping."""

from __future__ import annotations

from collections.abc import Callable, Mapping
from typing import Any

from ..errors import CalibTimeoutError, DeviceError, ProtocolError, UsageError

__all__ = ["SdkBusBase"]

COMM_SUCCESS = 0


class SdkBusBase:
    """Register lookup, retries and error mapping shared by :class:`FeetechBus` and :class:`DynamixelBus`."""

    vendor = ""
    port: str
    motors: Mapping[int, str]
    retries: int
    _tables: Mapping[str, Mapping[str, tuple[int, int]]]
    _ph: Any
    _sdk: Any

    def _entry(self, motor_id: int, register: str) -> tuple[int, int]:
        if motor_id not in self.motors:
            raise UsageError(
                f"{self.port}: motor id {motor_id} is not on this bus (ids {sorted(self.motors)})"
            )
        table = self._tables[self.motors[motor_id]]
        if register not in table:
            raise UsageError(
                f"{self.port}: motor {motor_id} ({self.motors[motor_id]}) has no register {register!r}"
            )
        return table[register]

    def has_register(self, motor_id: int, register: str) -> bool:
        """Whether that motor's control table has the register."""
        return motor_id in self.motors and register in self._tables[self.motors[motor_id]]

    def _call(
        self, what: str, motor_id: int | None, register: str, fn: Callable[[], tuple[Any, int, int]]
    ) -> Any:
        """Run an SDK call with retries; map failures to DeviceError / CalibTimeoutError / ProtocolError."""
        result, error, value = COMM_SUCCESS, 0, None
        who = f"motor {motor_id}" if motor_id is not None else "motors"
        for _ in range(self.retries + 1):
            value, result, error = fn()
            if result == COMM_SUCCESS and error == 0:
                return value
            if result == COMM_SUCCESS:
                break  # the motor answered with an error status: retrying will not help
        if result == COMM_SUCCESS:
            raise DeviceError(
                f"{self.port}: {who}: {what} {register!r} failed: {self._ph.getRxPacketError(error)}"
            )
        text = self._ph.getTxRxResult(result)
        msg = f"{self.port}: {who}: {what} {register!r} failed after {self.retries + 1} tries: {text}"
        if result == self._sdk.COMM_RX_TIMEOUT:
            raise CalibTimeoutError(msg)
        if result == self._sdk.COMM_RX_CORRUPT:
            raise ProtocolError(msg)
        raise DeviceError(msg)
