"""Damiao command frames of the non-MIT control modes (openarm_can only; LeRobot speaks MIT alone).

Pure Python. Each mode has its own id offset on ESC_ID (:data:`~robocal.backends.damiao.tables.MODE_ID_OFFSETS`)
and little-endian payloads (OAC ``dm_motor_control.cpp``):

* POS_VEL (CTRL_MODE 2), id ``0x100 + ESC_ID``: position float32, velocity limit float32 (rad, rad/s);
* VEL (3), id ``0x200 + ESC_ID``: velocity float32, **4 bytes** (rad/s);
* POS_FORCE (4), id ``0x300 + ESC_ID``: position float32, velocity ·100 as uint16 (0..100 rad/s), current limit
  per unit ·10000 as uint16 (0..1).

openarm_can computes the two POS_FORCE integers in float32 and truncates; :func:`encode_pos_force` does the same
(0.3 per unit → 3000, not the 2999 a float64 product would give).
"""

from __future__ import annotations

import math
import struct
from dataclasses import dataclass

from ...errors import ProtocolError, UsageError
from .protocol import Frame, command_id
from .tables import ControlMode

__all__ = [
    "PosForceCommand",
    "decode_pos_force",
    "decode_pos_vel",
    "decode_vel",
    "encode_pos_force",
    "encode_pos_vel",
    "encode_vel",
]


def _f32(x: float, what: str) -> float:
    if not math.isfinite(x):
        raise UsageError(f"{what}: cannot encode {x}; expected a finite number")
    return float(struct.unpack("<f", struct.pack("<f", x))[0])


def _scaled_u16(x: float, scale: float, top: int, what: str) -> int:
    """``trunc(f32(f32(x)·scale))`` clamped to ``0..top``: openarm_can's float32 arithmetic."""
    product = _f32(_f32(x, what) * scale, what)
    return min(max(int(product), 0), top)


def _payload(data: bytes, length: int, what: str) -> bytes:
    if len(data) != length:
        raise ProtocolError(f"{what}: payload has {len(data)} bytes; expected {length}")
    return bytes(data)


def encode_pos_vel(esc_id: int, position_rad: float, velocity_limit_rad_s: float) -> Frame:
    """POS_VEL command: go to ``position_rad`` at up to ``velocity_limit_rad_s``.

    Raises:
        UsageError: A value is not finite, or the id does not fit 11 bits with the mode's offset.
    """
    data = struct.pack("<ff", _f32(position_rad, "position"), _f32(velocity_limit_rad_s, "velocity limit"))
    return command_id(esc_id, ControlMode.POS_VEL), data


def decode_pos_vel(data: bytes) -> tuple[float, float]:
    """``(position_rad, velocity_limit_rad_s)`` of a POS_VEL payload."""
    p, v = struct.unpack("<ff", _payload(data, 8, "POS_VEL command"))
    return float(p), float(v)


def encode_vel(esc_id: int, velocity_rad_s: float) -> Frame:
    """VEL command (4 data bytes)."""
    return command_id(esc_id, ControlMode.VEL), struct.pack("<f", _f32(velocity_rad_s, "velocity"))


def decode_vel(data: bytes) -> float:
    """The velocity, rad/s, of a VEL payload."""
    return float(struct.unpack("<f", _payload(data, 4, "VEL command"))[0])


@dataclass(frozen=True)
class PosForceCommand:
    """A decoded POS_FORCE command.

    Attributes:
        position_rad: Target position, rad.
        velocity_rad_s: Speed, rad/s (0.01 steps, 0..100).
        current_limit_pu: Current limit as a share of the maximum (0.0001 steps, 0..1).
    """

    position_rad: float
    velocity_rad_s: float
    current_limit_pu: float


def encode_pos_force(esc_id: int, cmd: PosForceCommand) -> Frame:
    """POS_FORCE command, speed and current limit clamped to their ranges."""
    v = _scaled_u16(cmd.velocity_rad_s, 100.0, 10000, "velocity")
    i = _scaled_u16(cmd.current_limit_pu, 10000.0, 10000, "current limit")
    data = struct.pack("<fHH", _f32(cmd.position_rad, "position"), v, i)
    return command_id(esc_id, ControlMode.POS_FORCE), data


def decode_pos_force(data: bytes) -> PosForceCommand:
    """The fields of a POS_FORCE payload."""
    p, v, i = struct.unpack("<fHH", _payload(data, 8, "POS_FORCE command"))
    return PosForceCommand(float(p), v / 100.0, i / 10000.0)
