"""Damiao CAN frames: MIT command and state packing, special commands, register access, state codes as errors.

Pure Python (no python-can): a frame is ``(arbitration_id, data)`` with an 11-bit standard id. Layout (LR
``damiao.py``, OAC ``dm_motor_control.cpp``, DMP ``motor.py``; docs/damiao.md)::

    MIT command  to ESC_ID    q u16 | dq u12 | kp u12 | kd u12 | tau u12         (big-endian bit string)
    state        from MST_ID  id u4 + state u4 (D0) | q u16 | dq u12 | tau u12 | T_mos u8 | T_rotor u8
    special      to ESC_ID    FF FF FF FF FF FF FF cmd      (FC enable, FD disable, FE set zero, FB clear error)
    refresh      to 0x7FF     id_lo id_hi CC 00 00 00 00 00
    register     to 0x7FF     id_lo id_hi op rid value(4, LE)  (op 33 read, 55 write, AA save)

Fields map linearly onto ``[lo, hi]`` with ``u = trunc((x − lo)/(hi − lo)·(2^bits − 1))`` after clamping — the
truncating encoder every host stack uses — and back with ``x = u/(2^bits − 1)·(hi − lo) + lo``.
"""

from __future__ import annotations

import math
import struct
from dataclasses import dataclass

from ...errors import ProtocolError, UsageError
from .faults import fault_error
from .tables import (
    CMD_CLEAR_ERROR,
    CMD_DISABLE,
    CMD_ENABLE,
    CMD_SET_ZERO,
    CONFIG_ID,
    ID_MAX,
    KD_MAX,
    KP_MAX,
    MODE_ID_OFFSETS,
    OP_READ,
    OP_REFRESH,
    OP_SAVE,
    OP_WRITE,
    REGISTERS,
    STATE_NAMES,
    ControlMode,
    MotorLimits,
    Register,
    State,
)

__all__ = [
    "SPECIAL_COMMANDS",
    "ConfigRequest",
    "Frame",
    "MitCommand",
    "MotorState",
    "RegisterReply",
    "check_state",
    "clear_error_frame",
    "command_id",
    "decode_config_request",
    "decode_mit_command",
    "decode_register_reply",
    "decode_special",
    "decode_state",
    "disable_frame",
    "enable_frame",
    "encode_mit_command",
    "encode_register_reply",
    "encode_state",
    "float_to_uint",
    "pack_register_value",
    "refresh_frame",
    "register_read_frame",
    "register_write_frame",
    "save_frame",
    "set_zero_frame",
    "special_frame",
    "uint_to_float",
    "unpack_register_value",
]

Frame = tuple[int, bytes]
"""``(arbitration_id, data)`` of one classic-CAN frame with an 11-bit id."""

SPECIAL_COMMANDS: dict[int, str] = {
    CMD_ENABLE: "enable",
    CMD_DISABLE: "disable",
    CMD_SET_ZERO: "set zero",
    CMD_CLEAR_ERROR: "clear error",
}
"""Last byte of a special frame → what it asks."""

_SPECIAL_PREFIX = b"\xff" * 7


# --------------------------------------------------------------------------------------------------- scaling
def float_to_uint(x: float, lo: float, hi: float, bits: int) -> int:
    """Clamp ``x`` to ``[lo, hi]`` and map it onto ``bits`` bits, truncating (as LR, OAC and DMP do).

    Raises:
        UsageError: ``x`` is not a finite number.
    """
    if not math.isfinite(x):
        raise UsageError(f"cannot encode {x} into a {bits}-bit field; expected a finite number")
    x = min(max(x, lo), hi)
    return int((x - lo) / (hi - lo) * ((1 << bits) - 1))


def uint_to_float(u: int, lo: float, hi: float, bits: int, *, centred: bool = False) -> float:
    """The value ``u`` stands for: the bottom of its cell (the host stacks' decoder) or, ``centred``, its middle.

    The encoder truncates, so the plain decoder reads half a step low on average; ``centred`` returns
    ``(u + ½)`` steps, clamped to ``[lo, hi]``.
    """
    step = (hi - lo) / ((1 << bits) - 1)
    if not centred:
        return u * step + lo
    return min(max((u + 0.5) * step + lo, lo), hi)


def _check_id(can_id: int, what: str = "ESC_ID") -> int:
    if not 0 <= can_id <= ID_MAX:
        raise UsageError(f"{what} {can_id:#x} is not an 11-bit CAN id (0..{ID_MAX:#x})")
    return can_id


def _check_data(data: bytes, what: str, length: int = 8) -> bytes:
    if len(data) != length:
        raise ProtocolError(f"{what}: payload has {len(data)} bytes; expected {length}")
    return bytes(data)


def command_id(esc_id: int, mode: ControlMode = ControlMode.MIT) -> int:
    """Arbitration id of ``mode``'s command frames to a motor listening on ``esc_id`` (OAC: +0x100 per mode).

    Raises:
        UsageError: The id, or id plus the mode's offset, is not an 11-bit id.
    """
    return _check_id(_check_id(esc_id) + MODE_ID_OFFSETS[mode], f"{mode.name} command id")


# ------------------------------------------------------------------------------------------------ MIT command
@dataclass(frozen=True)
class MitCommand:
    """One MIT-mode command: the motor applies ``kp·(q_cmd − q) + kd·(dq_cmd − dq) + torque`` (output frame).

    Attributes:
        position_rad: Target position q, rad (±PMAX).
        velocity_rad_s: Target velocity dq, rad/s (±VMAX).
        kp: Stiffness, N·m/rad (0..500).
        kd: Damping, N·m·s/rad (0..5).
        torque_nm: Feed-forward torque, N·m (±TMAX).
    """

    position_rad: float
    velocity_rad_s: float
    kp: float
    kd: float
    torque_nm: float


def encode_mit_command(esc_id: int, cmd: MitCommand, limits: MotorLimits) -> Frame:
    """The MIT frame for ``cmd``, each field clamped to its range; ``MitCommand(0, 0, 0, 0, 0)`` is limp.

    Raises:
        UsageError: A field is not finite, or ``esc_id`` is not an 11-bit id.
    """
    q = float_to_uint(cmd.position_rad, -limits.p_max_rad, limits.p_max_rad, 16)
    dq = float_to_uint(cmd.velocity_rad_s, -limits.v_max_rad_s, limits.v_max_rad_s, 12)
    kp = float_to_uint(cmd.kp, 0.0, KP_MAX, 12)
    kd = float_to_uint(cmd.kd, 0.0, KD_MAX, 12)
    tau = float_to_uint(cmd.torque_nm, -limits.t_max_nm, limits.t_max_nm, 12)
    bits = (q << 48) | (dq << 36) | (kp << 24) | (kd << 12) | tau
    return command_id(esc_id), bits.to_bytes(8, "big")


def decode_mit_command(data: bytes, limits: MotorLimits) -> MitCommand:
    """Read an MIT frame's fields back (what a simulated motor does with it).

    Raises:
        ProtocolError: The payload is not 8 bytes.
    """
    bits = int.from_bytes(_check_data(data, "MIT command"), "big")
    return MitCommand(
        position_rad=uint_to_float(bits >> 48, -limits.p_max_rad, limits.p_max_rad, 16),
        velocity_rad_s=uint_to_float((bits >> 36) & 0xFFF, -limits.v_max_rad_s, limits.v_max_rad_s, 12),
        kp=uint_to_float((bits >> 24) & 0xFFF, 0.0, KP_MAX, 12),
        kd=uint_to_float((bits >> 12) & 0xFFF, 0.0, KD_MAX, 12),
        torque_nm=uint_to_float(bits & 0xFFF, -limits.t_max_nm, limits.t_max_nm, 12),
    )


# ------------------------------------------------------------------------------------------------ state frame
@dataclass(frozen=True)
class MotorState:
    """One decoded state (feedback) frame.

    Attributes:
        motor_id: Low nibble of byte 0: the low 4 bits of the motor's id.
        state: High nibble of byte 0: a :class:`~robocal.backends.damiao.tables.State` code (or an unknown one).
        position_rad: Output position, rad, relative to the motor's stored zero (±PMAX).
        velocity_rad_s: Output velocity, rad/s (±VMAX).
        torque_nm: Output torque, N·m (±TMAX).
        mos_temp_c: MOSFET temperature, °C.
        rotor_temp_c: Rotor (coil) temperature, °C.
    """

    motor_id: int
    state: int
    position_rad: float
    velocity_rad_s: float
    torque_nm: float
    mos_temp_c: int
    rotor_temp_c: int

    @property
    def state_name(self) -> str:
        """The state in words (``"enabled"``, ``"over-voltage"``, ``"unknown state 0x3"``)."""
        return (
            STATE_NAMES[State(self.state)]
            if self.state in State._value2member_map_
            else (f"unknown state {self.state:#x}")
        )


def encode_state(state: MotorState, limits: MotorLimits) -> bytes:
    """The 8 data bytes a motor sends for ``state`` (the simulator's side; values clamped to their ranges).

    Raises:
        UsageError: A field is not finite, or an id, code or temperature does not fit its field.
    """
    if not (0 <= state.motor_id <= 0xF and 0 <= state.state <= 0xF):
        raise UsageError(f"motor id {state.motor_id} and state {state.state} must each fit 4 bits")
    if not (0 <= state.mos_temp_c <= 0xFF and 0 <= state.rotor_temp_c <= 0xFF):
        raise UsageError(f"temperatures {state.mos_temp_c}/{state.rotor_temp_c} °C must each fit 0..255")
    q = float_to_uint(state.position_rad, -limits.p_max_rad, limits.p_max_rad, 16)
    dq = float_to_uint(state.velocity_rad_s, -limits.v_max_rad_s, limits.v_max_rad_s, 12)
    tau = float_to_uint(state.torque_nm, -limits.t_max_nm, limits.t_max_nm, 12)
    head = (state.state << 4) | state.motor_id
    return (
        bytes([head])
        + ((q << 24) | (dq << 12) | tau).to_bytes(5, "big")
        + bytes([state.mos_temp_c, state.rotor_temp_c])
    )


def decode_state(data: bytes, limits: MotorLimits, *, centred: bool = False) -> MotorState:
    """Decode a state frame with ``limits`` (read from the motor's PMAX / VMAX / TMAX where possible).

    ``centred=False`` reads as LeRobot and openarm_can do (the cell's bottom edge); ``True`` reads the cell's
    middle (:func:`uint_to_float`). The state code is returned as sent; :func:`check_state` judges it.

    Raises:
        ProtocolError: The payload is not 8 bytes.
    """
    raw = _check_data(data, "state frame")
    bits = int.from_bytes(raw[1:6], "big")
    return MotorState(
        motor_id=raw[0] & 0x0F,
        state=raw[0] >> 4,
        position_rad=uint_to_float(bits >> 24, -limits.p_max_rad, limits.p_max_rad, 16, centred=centred),
        velocity_rad_s=uint_to_float(
            (bits >> 12) & 0xFFF, -limits.v_max_rad_s, limits.v_max_rad_s, 12, centred=centred
        ),
        torque_nm=uint_to_float(bits & 0xFFF, -limits.t_max_nm, limits.t_max_nm, 12, centred=centred),
        mos_temp_c=raw[6],
        rotor_temp_c=raw[7],
    )


# --------------------------------------------------------------------------------------------- special frames
def special_frame(esc_id: int, cmd: int) -> Frame:
    """``FF×7 cmd`` to ``esc_id``.

    Raises:
        UsageError: ``cmd`` is not one of :data:`SPECIAL_COMMANDS`, or the id is not an 11-bit id.
    """
    if cmd not in SPECIAL_COMMANDS:
        raise UsageError(
            f"special command {cmd:#04x}; valid: {', '.join(f'{c:#04x}' for c in SPECIAL_COMMANDS)}"
        )
    return _check_id(esc_id), _SPECIAL_PREFIX + bytes([cmd])


def enable_frame(esc_id: int) -> Frame:
    """Switch the motor on (0xFC)."""
    return special_frame(esc_id, CMD_ENABLE)


def disable_frame(esc_id: int) -> Frame:
    """Switch the motor off (0xFD)."""
    return special_frame(esc_id, CMD_DISABLE)


def set_zero_frame(esc_id: int) -> Frame:
    """Make the current output position zero (0xFE); whether it costs a flash cycle is not known."""
    return special_frame(esc_id, CMD_SET_ZERO)


def clear_error_frame(esc_id: int) -> Frame:
    """Clear a latched error (0xFB)."""
    return special_frame(esc_id, CMD_CLEAR_ERROR)


def decode_special(data: bytes) -> int | None:
    """The command byte of a special frame, or None when ``data`` is not one (e.g. an MIT frame).

    An MIT frame reads the same only with every field at the top of its range (torque within 0.2 % of +TMAX),
    the ambiguity the motors themselves have; the byte is returned only for the four known commands.
    """
    raw = bytes(data)
    if len(raw) == 8 and raw[:7] == _SPECIAL_PREFIX and raw[7] in SPECIAL_COMMANDS:
        return raw[7]
    return None


# ------------------------------------------------------------------------------------- refresh and registers
def _config_frame(esc_id: int, op: int, rid: int, value: bytes = bytes(4)) -> Frame:
    _check_id(esc_id)
    return CONFIG_ID, bytes([esc_id & 0xFF, esc_id >> 8, op, rid]) + value


def refresh_frame(esc_id: int) -> Frame:
    """Ask the motor on ``esc_id`` for a state frame (to 0x7FF; how LeRobot reads every position)."""
    return _config_frame(esc_id, OP_REFRESH, 0)


def _info(rid: int) -> Register:
    if rid not in Register._value2member_map_:
        raise UsageError(f"unknown Damiao register {rid}; known: {', '.join(str(int(r)) for r in Register)}")
    return Register(rid)


def pack_register_value(rid: int, value: float) -> bytes:
    """A register's value as its 4 little-endian bytes: uint32 or float32 by :data:`REGISTERS`.

    Raises:
        UsageError: Unknown register, a non-finite value, or an integer register given a value that is not a
            whole number in 0..2^32 − 1.
    """
    reg = _info(rid)
    if not math.isfinite(value):
        raise UsageError(f"register {reg.name}: cannot write {value}; expected a finite number")
    if REGISTERS[reg].kind == "f32":
        return struct.pack("<f", float(value))
    if value != int(value) or not 0 <= int(value) <= 0xFFFFFFFF:
        raise UsageError(f"register {reg.name}: {value} is not a whole number in 0..4294967295")
    return struct.pack("<I", int(value))


def unpack_register_value(rid: int, raw4: bytes) -> float:
    """4 little-endian bytes as register ``rid``'s value (an integer register's as a whole float).

    Raises:
        UsageError: Unknown register.
        ProtocolError: Not 4 bytes.
    """
    reg = _info(rid)
    raw = _check_data(raw4, f"register {reg.name} value", 4)
    if REGISTERS[reg].kind == "f32":
        return float(struct.unpack("<f", raw)[0])
    return float(struct.unpack("<I", raw)[0])


def register_read_frame(esc_id: int, rid: int) -> Frame:
    """Read register ``rid`` of the motor on ``esc_id`` (op 0x33)."""
    return _config_frame(esc_id, OP_READ, _info(rid))


def register_write_frame(esc_id: int, rid: int, value: float) -> Frame:
    """Write register ``rid`` in RAM (op 0x55; lost at power-off unless saved).

    Raises:
        UsageError: The register is read-only, unknown, or the value does not fit its type.
    """
    reg = _info(rid)
    if not REGISTERS[reg].writable:
        raise UsageError(f"register {reg.name} ({int(reg)}) is read-only")
    return _config_frame(esc_id, OP_WRITE, reg, pack_register_value(reg, value))


def save_frame(esc_id: int) -> Frame:
    """Save every register to flash (op 0xAA, byte 3 = 0 as openarm_can sends; ~10 000 cycles per motor)."""
    return _config_frame(esc_id, OP_SAVE, 0)


@dataclass(frozen=True)
class RegisterReply:
    """A motor's answer to a register read (op 0x33) or its echo of a write (op 0x55).

    Attributes:
        can_id: The motor's ESC_ID (bytes 0-1).
        op: ``OP_READ`` or ``OP_WRITE``.
        register: The register id.
        value: Its value (an integer register's as a whole float).
    """

    can_id: int
    op: int
    register: int
    value: float


def encode_register_reply(can_id: int, op: int, rid: int, value: float) -> bytes:
    """The data bytes of a register reply (the simulator's side)."""
    if op not in (OP_READ, OP_WRITE):
        raise UsageError(f"register reply op {op:#04x}; valid: {OP_READ:#04x}, {OP_WRITE:#04x}")
    _check_id(can_id)
    return bytes([can_id & 0xFF, can_id >> 8, op, _info(rid)]) + pack_register_value(rid, value)


def decode_register_reply(data: bytes) -> RegisterReply:
    """Decode a register reply.

    Raises:
        ProtocolError: Not 8 bytes, not a read/write reply, or an unknown register.
    """
    raw = _check_data(data, "register reply")
    if raw[2] not in (OP_READ, OP_WRITE):
        raise ProtocolError(
            f"register reply op byte {raw[2]:#04x}; expected {OP_READ:#04x} or {OP_WRITE:#04x}"
        )
    if raw[3] not in Register._value2member_map_:
        raise ProtocolError(f"register reply names unknown register {raw[3]}")
    return RegisterReply(raw[0] | (raw[1] << 8), raw[2], raw[3], unpack_register_value(raw[3], raw[4:8]))


@dataclass(frozen=True)
class ConfigRequest:
    """A host frame to 0x7FF as a motor reads it: refresh, register read / write, or save.

    Attributes:
        can_id: ESC_ID of the motor addressed (bytes 0-1).
        op: ``OP_REFRESH``, ``OP_READ``, ``OP_WRITE`` or ``OP_SAVE``.
        register: Byte 3 (the register id; 0 or 1 for a save, 0 for a refresh).
        value: Bytes 4-7 as sent (decode a write's with :func:`unpack_register_value`).
    """

    can_id: int
    op: int
    register: int
    value: bytes


def decode_config_request(data: bytes) -> ConfigRequest:
    """Read a frame sent to 0x7FF (the simulator's side).

    Raises:
        ProtocolError: Not 8 bytes, or an op byte no source names.
    """
    raw = _check_data(data, "0x7FF frame")
    if raw[2] not in (OP_REFRESH, OP_READ, OP_WRITE, OP_SAVE):
        raise ProtocolError(f"0x7FF frame op byte {raw[2]:#04x}; expected one of 0xcc, 0x33, 0x55, 0xaa")
    return ConfigRequest(raw[0] | (raw[1] << 8), raw[2], raw[3], raw[4:8])


# ------------------------------------------------------------------------------------------- state checking
def check_state(state: MotorState, motor: str) -> MotorState:
    """``state`` unchanged when the motor is disabled or enabled.

    Raises:
        DamiaoFaultError: The motor reports an error state (one subclass per code, :mod:`.faults`).
        DamiaoUnknownStateError: The state code is one no source names.
    """
    err = fault_error(state.state, motor)
    if err is not None:
        raise err
    return state
