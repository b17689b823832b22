"""Shared machinery of the vendor-SDK servo buses: retries and error mapping."""

from __future__ import annotations

import contextlib
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

    _port_handler: Any

    def _drain(self) -> None:
        """Drop late bytes of a failed transfer so a retry cannot read a stale status packet."""
        ser = getattr(self._port_handler, "ser", None)
        if ser is not None:
            with contextlib.suppress(Exception):
                ser.reset_input_buffer()

    def _install_timeout(self, packet_timeout_ms: float | None) -> None:
        """Raise the SDK's per-packet timeout to at least ``packet_timeout_ms`` (on this port object only)."""
        if packet_timeout_ms is None:
            return
        handler = self._port_handler
        original = handler.setPacketTimeout

        def set_packet_timeout(packet_length: int) -> None:
            original(packet_length)
            handler.packet_timeout = max(handler.packet_timeout, float(packet_timeout_ms))

        handler.setPacketTimeout = set_packet_timeout

    def has_register(self, motor_id: int, register: str) -> bool:
        """Whether that motor's control table has the register."""
        return motor_id in self.motors and register in self._tables[self.motors[motor_id]]

    def _call(
        self, what: str, motor_id: int | None, register: str, fn: Callable[[], tuple[Any, int, int]]
    ) -> Any:
        """Run an SDK call with retries; map failures to DeviceError / CalibTimeoutError / ProtocolError."""
        result, error, value = COMM_SUCCESS, 0, None
        who = f"motor {motor_id}" if motor_id is not None else "motors"
        for attempt in range(self.retries + 1):
            if attempt:
                self._drain()
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
