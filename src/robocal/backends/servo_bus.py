"""The servo-bus protocol shared by the Feetech and Dynamixel backends (and their simulators).

Registers are named like LeRobot's control tables; values are decoded signed ints (sign-magnitude on Feetech,
two's complement on Dynamixel are handled by the bus).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Protocol

__all__ = ["ServoBus"]


class ServoBus(Protocol):
    """A serial servo bus: register reads/writes by name, sync read/write, retries and timeouts inside."""

    port: str
    vendor: str
    """``"feetech"`` or ``"dynamixel"``."""
    motors: Mapping[int, str]
    """Motor id → model name."""

    def resolution(self, motor_id: int) -> int:
        """Ticks per turn of that motor's model."""
        ...

    def ping(self, motor_id: int) -> int:
        """Model number reported by the motor."""
        ...

    def has_register(self, motor_id: int, register: str) -> bool:
        """Whether that motor's control table has the register."""
        ...

    def read(self, register: str, motor_id: int) -> int:
        """Read and decode one register of one motor."""
        ...

    def check_write(self, register: str, motor_id: int, value: int) -> None:
        """Raise what :meth:`write` would raise for this value (unknown register, does not fit), sending nothing."""
        ...

    def write(self, register: str, motor_id: int, value: int) -> None:
        """Encode and write one register of one motor (waits for the status packet)."""
        ...

    def sync_read(self, register: str, motor_ids: Sequence[int]) -> dict[int, int]:
        """Read one register of several motors in one instruction."""
        ...

    def sync_write(self, register: str, values: Mapping[int, int]) -> None:
        """Write one register of several motors in one instruction (no status packets)."""
        ...

    def close(self) -> None:
        """Close the port."""
        ...
