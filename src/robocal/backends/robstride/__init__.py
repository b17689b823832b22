"""Robstride motors over CAN (the "private protocol", extended 29-bit frames), on python-can.

python-can is imported lazily when a bus is opened; the protocol module is pure Python.
"""

from __future__ import annotations

from .bus import MotorSpec as MotorSpec
from .bus import RobstrideBus as RobstrideBus

__all__ = ["MotorSpec", "RobstrideBus"]
