"""Robstride "private protocol" frames: 29-bit identifiers, payload encoders and decoders.

Pure Python (no python-can): a frame is ``(arbitration_id, data)``, an extended 29-bit id and 8 data bytes.

Identifier layout (bits)::

    28..24  communication type
    23..8   "data area 2": host → motor usually bits 15..8 = host id; type 1 carries the torque u16;
            motor → host type 2: bits 23..22 mode, 21..16 faults, 15..8 motor id
    7..0    target id (motor id host → motor, host id motor → host)

Scaling of the type-2 feedback and type-1 command uses the per-model ranges from the official manuals
(:data:`MODELS`); several public SDKs ship wrong velocity/torque ranges for RS00, RS03, RS05 and RS06.
"""

from __future__ import annotations

import math
import struct
from dataclasses import dataclass
from enum import IntEnum

from ...errors import ProtocolError, UsageError

__all__ = [
    "DEFAULT_HOST_ID",
    "FIRMWARE_QUERY",
    "MODELS",
    "PARAMS",
    "P_MAX_RAD",
    "SAVE_PAYLOAD",
    "CommType",
    "Feedback",
    "ModelLimits",
    "Param",
    "decode_fault_report",
    "decode_feedback",
    "decode_firmware_reply",
    "decode_mit_command",
    "decode_param_reply",
    "encode_feedback",
    "encode_firmware_reply",
    "encode_mit_command",
    "encode_param_read",
    "encode_param_reply",
    "encode_param_write",
    "float_to_uint",
    "float_to_uint_7fff",
    "make_id",
    "model_limits",
    "pack_param_value",
    "split_id",
    "uint_to_float",
    "uint_to_float_7fff",
    "uint_to_float_centred",
    "unpack_param_value",
]

DEFAULT_HOST_ID = 0xFD
"""Host CAN id used in the manual's examples."""
P_MAX_RAD = 4.0 * math.pi
"""Position range of the type-2 feedback and type-1 command: ±4π rad (manual: ±12.57)."""
FIRMWARE_QUERY = bytes([0x00, 0xC4, 0, 0, 0, 0, 0, 0])
"""Type-4 payload that asks for the firmware version instead of stopping the motor."""
SAVE_PAYLOAD = bytes([1, 2, 3, 4, 5, 6, 7, 8])
"""Type-22 payload (save parameters)."""


class CommType(IntEnum):
    """Communication types (identifier bits 28..24) used by robocal."""

    GET_ID = 0
    MIT = 1
    FEEDBACK = 2
    ENABLE = 3
    STOP = 4
    SET_ZERO = 6
    SET_ID = 7
    PARAM_READ = 17
    PARAM_WRITE = 18
    FAULT = 21
    SAVE = 22


@dataclass(frozen=True)
class ModelLimits:
    """Private-protocol scaling ranges of one Robstride model (from the manual's ``#define`` block).

    Attributes:
        name: Canonical model name, e.g. ``"RS00"``.
        p_max_rad: Position range ±P, rad.
        v_max_rad_s: Velocity range ±V, rad/s.
        t_max_nm: Torque range ±T, N·m.
        kp_max: Kp range 0…Kp_max.
        kd_max: Kd range 0…Kd_max.
    """

    name: str
    p_max_rad: float
    v_max_rad_s: float
    t_max_nm: float
    kp_max: float
    kd_max: float


MODELS: dict[str, ModelLimits] = {
    m.name: m
    for m in (
        ModelLimits("RS00", P_MAX_RAD, 33.0, 14.0, 500.0, 5.0),
        ModelLimits("RS01", P_MAX_RAD, 44.0, 17.0, 500.0, 5.0),
        ModelLimits("RS02", P_MAX_RAD, 44.0, 17.0, 500.0, 5.0),
        ModelLimits("RS03", P_MAX_RAD, 20.0, 60.0, 5000.0, 100.0),
        ModelLimits("RS04", P_MAX_RAD, 15.0, 120.0, 5000.0, 100.0),
        ModelLimits("RS05", P_MAX_RAD, 50.0, 5.5, 500.0, 5.0),
        ModelLimits("RS06", P_MAX_RAD, 50.0, 36.0, 5000.0, 100.0),
        ModelLimits("EL05", P_MAX_RAD, 50.0, 5.5, 500.0, 5.0),
    )
}
"""Model name → private-protocol ranges (manual rev. 260428). Not the MIT-protocol chapter's numbers."""


def model_limits(model: str) -> ModelLimits:
    """Look up a model by name, accepting ``"rs-00"``, ``"rs00"``, ``"RS00"``.

    Raises:
        UsageError: Unknown model (the message lists the known ones).
    """
    key = model.strip().upper().replace("-", "").replace("_", "")
    if key not in MODELS:
        raise UsageError(f"unknown Robstride model {model!r}; expected one of {', '.join(MODELS)}")
    return MODELS[key]


class Param(IntEnum):
    """Parameter indices (read with type 17, written with type 18) relevant to calibration."""

    RUN_MODE = 0x7005
    LIMIT_TORQUE = 0x700B
    LIMIT_CUR = 0x7018
    MECH_POS = 0x7019
    MECH_VEL = 0x701B
    VBUS = 0x701C
    CAN_TIMEOUT = 0x7028
    ZERO_STA = 0x7029
    ADD_OFFSET = 0x702B


PARAMS: dict[int, tuple[str, str]] = {
    Param.RUN_MODE: ("run_mode", "u8"),
    Param.LIMIT_TORQUE: ("limit_torque", "f32"),
    Param.LIMIT_CUR: ("limit_cur", "f32"),
    Param.MECH_POS: ("mechPos", "f32"),
    Param.MECH_VEL: ("mechVel", "f32"),
    Param.VBUS: ("VBUS", "f32"),
    Param.CAN_TIMEOUT: ("canTimeout", "u32"),
    Param.ZERO_STA: ("zero_sta", "u8"),
    Param.ADD_OFFSET: ("add_offset", "f32"),
}
"""Parameter index → (name, type); type is one of ``u8``, ``u16``, ``u32``, ``f32``."""


# ------------------------------------------------------------------------------------------------ identifiers
def make_id(comm_type: int, data16: int, target: int) -> int:
    """Build a 29-bit identifier from its three fields.

    Args:
        comm_type: Communication type, 0…31.
        data16: Data area 2 (bits 23..8), 0…0xFFFF.
        target: Bits 7..0, 0…255.

    Returns:
        The arbitration id.
    """
    if not (0 <= comm_type <= 0x1F and 0 <= data16 <= 0xFFFF and 0 <= target <= 0xFF):
        raise ProtocolError(
            f"identifier fields out of range: type {comm_type}, data {data16:#x}, id {target}"
        )
    return (comm_type << 24) | (data16 << 8) | target


def split_id(arbitration_id: int) -> tuple[int, int, int]:
    """Split a 29-bit identifier into ``(comm_type, data16, low8)``."""
    if not 0 <= arbitration_id < (1 << 29):
        raise ProtocolError(f"identifier {arbitration_id:#x} is not a 29-bit extended id")
    return (arbitration_id >> 24) & 0x1F, (arbitration_id >> 8) & 0xFFFF, arbitration_id & 0xFF


# --------------------------------------------------------------------------------------------------- scaling
def float_to_uint(x: float, x_min: float, x_max: float, bits: int = 16) -> int:
    """The manual's encoder: ``(x − min)·(2^bits − 1)/(max − min)``, clamped and truncated.

    Raises:
        UsageError: ``x`` is not a finite number.
    """
    if not math.isfinite(x):
        raise UsageError(f"cannot encode {x} into a {bits}-bit field; expected a finite number")
    span = x_max - x_min
    x = min(max(x, x_min), x_max)
    return int((x - x_min) * ((1 << bits) - 1) / span)


def uint_to_float(u: int, x_min: float, x_max: float, bits: int = 16) -> float:
    """The manual's decoder: ``u/(2^bits − 1)·(max − min) + min``."""
    return u / ((1 << bits) - 1) * (x_max - x_min) + x_min


def uint_to_float_centred(u: int, x_min: float, x_max: float, bits: int = 16) -> float:
    """Unbiased decoder for values the manual's truncating encoder wrote: the centre of ``u``'s cell.

    :func:`float_to_uint` truncates, so ``u`` stands for every ``x`` in ``[u, u + 1)·LSB + min``; the manual's
    decoder :func:`uint_to_float` returns the cell's bottom edge, on average half an LSB (1.9e-4 rad for a
    position) below the true value. This returns ``(u + ½)·LSB + min``, clamped to ``[min, max]`` (so the
    midpoint 0x7FFF decodes to 0.0 exactly, as the ``0x7FFF`` variant does).
    """
    x = (u + 0.5) / ((1 << bits) - 1) * (x_max - x_min) + x_min
    return min(max(x, x_min), x_max)


def float_to_uint_7fff(x: float, limit: float) -> int:
    """The ``0x7FFF`` variant (Actuator-Control, robstride-dynamics): ``(x/limit + 1)·0x7FFF``, 16 bit."""
    if not math.isfinite(x):
        raise UsageError(f"cannot encode {x} into a 16-bit field; expected a finite number")
    x = min(max(x, -limit), limit)
    return min(int((x / limit + 1.0) * 0x7FFF), 0xFFFF)


def uint_to_float_7fff(u: int, limit: float) -> float:
    """The ``0x7FFF`` variant's decoder: ``(u/0x7FFF − 1)·limit``."""
    return (u / 0x7FFF - 1.0) * limit


def _check_data(data: bytes, what: str) -> bytes:
    if len(data) != 8:
        raise ProtocolError(f"{what}: payload has {len(data)} bytes; expected 8")
    return bytes(data)


# -------------------------------------------------------------------------------------------------- feedback
@dataclass(frozen=True)
class Feedback:
    """Decoded type-2 feedback frame (motor frame).

    Attributes:
        motor_id: Motor CAN id.
        host_id: Host CAN id the frame is addressed to.
        mode: 0 reset, 1 calibration, 2 run.
        faults: Fault bits 21..16 as a 6-bit number (bit 5 uncalibrated … bit 0 under-voltage).
        position_rad: Output angle, rad (±4π).
        velocity_rad_s: Output velocity, rad/s.
        torque_nm: Torque, N·m.
        temperature_c: Temperature, °C.
    """

    motor_id: int
    host_id: int
    mode: int
    faults: int
    position_rad: float
    velocity_rad_s: float
    torque_nm: float
    temperature_c: float


def encode_feedback(fb: Feedback, model: ModelLimits) -> tuple[int, bytes]:
    """Encode a type-2 feedback frame (what a motor sends)."""
    data16 = ((fb.mode & 0x3) << 14) | ((fb.faults & 0x3F) << 8) | (fb.motor_id & 0xFF)
    arb = make_id(CommType.FEEDBACK, data16, fb.host_id)
    p = float_to_uint(fb.position_rad, -model.p_max_rad, model.p_max_rad)
    v = float_to_uint(fb.velocity_rad_s, -model.v_max_rad_s, model.v_max_rad_s)
    t = float_to_uint(fb.torque_nm, -model.t_max_nm, model.t_max_nm)
    temp = min(max(round(fb.temperature_c * 10.0), 0), 0xFFFF)
    return arb, struct.pack(">HHHH", p, v, t, temp)


def decode_feedback(
    arbitration_id: int, data: bytes, model: ModelLimits, *, centred: bool = True
) -> Feedback:
    """Decode a type-2 (or type-24 active report) feedback frame with ``model``'s ranges.

    Position, velocity and torque are decoded to the centre of their quantisation cell
    (:func:`uint_to_float_centred`): the motor's encoder truncates, so the manual's decoder
    (``centred=False``) reads on average half an LSB low, which biased every sweep offset by −1.9e-4 rad.

    Raises:
        ProtocolError: Not a type-2/24 frame, or the payload is not 8 bytes.
    """
    comm, data16, host = split_id(arbitration_id)
    if comm not in (CommType.FEEDBACK, 24):
        raise ProtocolError(f"frame {arbitration_id:#010x} is type {comm}; expected feedback (type 2)")
    p, v, t, temp = struct.unpack(">HHHH", _check_data(data, "type-2 feedback"))
    dec = uint_to_float_centred if centred else uint_to_float
    return Feedback(
        motor_id=data16 & 0xFF,
        host_id=host,
        mode=(data16 >> 14) & 0x3,
        faults=(data16 >> 8) & 0x3F,
        position_rad=dec(p, -model.p_max_rad, model.p_max_rad),
        velocity_rad_s=dec(v, -model.v_max_rad_s, model.v_max_rad_s),
        torque_nm=dec(t, -model.t_max_nm, model.t_max_nm),
        temperature_c=temp / 10.0,
    )


# ----------------------------------------------------------------------------------------- MIT (type 1)
def encode_mit_command(
    motor_id: int,
    position_rad: float,
    velocity_rad_s: float,
    kp: float,
    kd: float,
    torque_nm: float,
    model: ModelLimits,
) -> tuple[int, bytes]:
    """Encode a type-1 operation-control (MIT) command; torque goes into the identifier.

    All values in the motor frame. ``(0, 0, 0, 0, 0)`` is the passive zero-torque command.
    """
    t = float_to_uint(torque_nm, -model.t_max_nm, model.t_max_nm)
    arb = make_id(CommType.MIT, t, motor_id)
    data = struct.pack(
        ">HHHH",
        float_to_uint(position_rad, -model.p_max_rad, model.p_max_rad),
        float_to_uint(velocity_rad_s, -model.v_max_rad_s, model.v_max_rad_s),
        float_to_uint(kp, 0.0, model.kp_max),
        float_to_uint(kd, 0.0, model.kd_max),
    )
    return arb, data


def decode_mit_command(
    arbitration_id: int, data: bytes, model: ModelLimits
) -> tuple[int, float, float, float, float, float]:
    """Decode a type-1 command into ``(motor_id, position, velocity, kp, kd, torque)`` (motor frame)."""
    comm, data16, motor = split_id(arbitration_id)
    if comm != CommType.MIT:
        raise ProtocolError(f"frame {arbitration_id:#010x} is type {comm}; expected MIT command (type 1)")
    p, v, kp, kd = struct.unpack(">HHHH", _check_data(data, "type-1 command"))
    return (
        motor,
        uint_to_float(p, -model.p_max_rad, model.p_max_rad),
        uint_to_float(v, -model.v_max_rad_s, model.v_max_rad_s),
        uint_to_float(kp, 0.0, model.kp_max),
        uint_to_float(kd, 0.0, model.kd_max),
        uint_to_float(data16, -model.t_max_nm, model.t_max_nm),
    )


# ---------------------------------------------------------------------------------------------- parameters
def pack_param_value(index: int, value: float) -> bytes:
    """Pack a parameter value into 4 little-endian bytes according to its type in :data:`PARAMS`."""
    kind = PARAMS.get(index, ("", "f32"))[1]
    if kind == "f32":
        return struct.pack("<f", float(value))
    width = {"u8": 1, "u16": 2, "u32": 4}[kind]
    iv = int(value)
    if not 0 <= iv < (1 << (8 * width)):
        raise UsageError(f"parameter {index:#06x}: value {value} does not fit {kind}")
    return iv.to_bytes(width, "little").ljust(4, b"\0")


def unpack_param_value(index: int, raw4: bytes) -> float:
    """Unpack 4 little-endian bytes according to the parameter's type (``f32`` → float, else int)."""
    kind = PARAMS.get(index, ("", "f32"))[1]
    if kind == "f32":
        return float(struct.unpack("<f", raw4)[0])
    width = {"u8": 1, "u16": 2, "u32": 4}[kind]
    return float(int.from_bytes(raw4[:width], "little"))


def encode_param_read(host_id: int, motor_id: int, index: int) -> tuple[int, bytes]:
    """Type-17 read request: data ``idx u16 LE, 0, 0, 0×4``."""
    return make_id(CommType.PARAM_READ, host_id & 0xFF, motor_id), struct.pack("<HHI", index, 0, 0)


def encode_param_write(host_id: int, motor_id: int, index: int, value: float) -> tuple[int, bytes]:
    """Type-18 write request (the value is lost at power-off unless saved with type 22)."""
    return make_id(CommType.PARAM_WRITE, host_id & 0xFF, motor_id), struct.pack(
        "<HH", index, 0
    ) + pack_param_value(index, value)


def encode_param_reply(
    motor_id: int, host_id: int, index: int, value: float, ok: bool = True
) -> tuple[int, bytes]:
    """Type-17 reply (what a motor sends): id bits 23..16 = status (0 ok, 1 fail), 15..8 motor, 7..0 host."""
    data16 = ((0 if ok else 1) << 8) | (motor_id & 0xFF)
    return make_id(CommType.PARAM_READ, data16, host_id), struct.pack("<HH", index, 0) + pack_param_value(
        index, value
    )


def decode_param_reply(arbitration_id: int, data: bytes) -> tuple[int, int, bool, float]:
    """Decode a type-17 reply into ``(motor_id, index, ok, value)``.

    Raises:
        ProtocolError: Wrong type or payload length.
    """
    comm, data16, _host = split_id(arbitration_id)
    if comm != CommType.PARAM_READ:
        raise ProtocolError(
            f"frame {arbitration_id:#010x} is type {comm}; expected a parameter reply (type 17)"
        )
    payload = _check_data(data, "type-17 reply")
    index = struct.unpack("<H", payload[:2])[0]
    ok = (data16 >> 8) == 0
    return data16 & 0xFF, index, ok, unpack_param_value(index, payload[4:8])


# ------------------------------------------------------------------------------------------ firmware version
def encode_firmware_reply(
    motor_id: int, host_id: int, version: tuple[int, int, int, int]
) -> tuple[int, bytes]:
    """Reply to the type-4 ``00 C4`` query: type 4 to the host, data ``00 C4 a b c d 0 0`` for ``a.b.c.d``.

    The reply layout is robocal's reading of the manual (the version digits follow the query bytes);
    verify it on the target firmware.
    """
    return make_id(CommType.STOP, motor_id & 0xFF, host_id), bytes([0x00, 0xC4, *version, 0, 0])


def decode_firmware_reply(arbitration_id: int, data: bytes) -> tuple[int, str]:
    """Decode the firmware version reply into ``(motor_id, "a.b.c.d")``."""
    comm, data16, _host = split_id(arbitration_id)
    payload = _check_data(data, "firmware version reply")
    if comm != CommType.STOP or payload[:2] != b"\x00\xc4":
        raise ProtocolError(f"frame {arbitration_id:#010x} is not a firmware version reply")
    return data16 & 0xFF, ".".join(str(b) for b in payload[2:6])


def decode_fault_report(data: bytes) -> tuple[int, int]:
    """Type-21 payload → ``(faults, warnings)`` (two little-endian u32)."""
    if len(data) != 8:
        raise ProtocolError(f"type-21 fault report: payload has {len(data)} bytes; expected 8")
    return int.from_bytes(data[:4], "little"), int.from_bytes(data[4:], "little")
