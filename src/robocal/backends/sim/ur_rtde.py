"""Simulated UR RTDE server (TCP 30004), protocol version 2: outputs and inputs.

Packets are ``uint16 BE size`` (header included), ``uint8 type``, payload. Served: REQUEST_PROTOCOL_VERSION
('V', version 2 accepted), GET_URCONTROL_VERSION ('v'), SETUP_OUTPUTS ('O': frequency, comma-separated names,
a trailing comma allowed as ur_rtde sends it; the reply is a recipe id and the types, ``NOT_FOUND`` for a name
not modelled), SETUP_INPUTS ('I': recipe id and types, see :mod:`.ur_rtde_inputs`), input DATA_PACKAGEs ('U'
from the client: applied at once), START ('S') and PAUSE ('P'); after START each output recipe is sent as a
DATA_PACKAGE ('U') at its frequency. Every output of ur_rtde's
``RTDEReceiveInterface`` default recipe is served with its exact type. Sources and assumptions: docs/sim.md.
"""

from __future__ import annotations

import math
import select
import socket
import struct
import time
from collections.abc import Callable
from dataclasses import dataclass

from ...core.dh import DHParameters, fk_dh
from ...core.lifecycle import StartsOnEnter
from ...core.se3 import rotvec_from_matrix
from ._sockets import LoopbackServer
from .ur_arm_state import RobotModeSample, UrArmState
from .ur_realtime import joint_path
from .ur_rtde_inputs import RtdeInputs

__all__ = ["RTDE_OUTPUT_TYPES", "RTDE_TYPE_FORMATS", "SimUrRtde", "encode_rtde"]

RTDE_TYPE_FORMATS: dict[str, str] = {
    "DOUBLE": "d",
    "VECTOR6D": "6d",
    "VECTOR3D": "3d",
    "VECTOR6INT32": "6i",
    "INT32": "i",
    "UINT32": "I",
    "UINT64": "Q",
    "UINT8": "B",
    "BOOL": "?",
}
"""Big-endian struct codes of the RTDE value types."""

_V6 = [
    "target_q",
    "target_qd",
    "target_qdd",
    "target_current",
    "target_moment",
    "actual_q",
    "actual_qd",
    "actual_current",
    "joint_control_output",
    "actual_TCP_pose",
    "actual_TCP_speed",
    "actual_TCP_force",
    "target_TCP_pose",
    "target_TCP_speed",
    "joint_temperatures",
    "actual_joint_voltage",
    "tcp_offset",
]
_D = [
    "timestamp",
    "actual_execution_time",
    "speed_scaling",
    "target_speed_fraction",
    "actual_momentum",
    "actual_main_voltage",
    "actual_robot_voltage",
    "actual_robot_current",
    "standard_analog_input0",
    "standard_analog_input1",
    "standard_analog_output0",
    "standard_analog_output1",
]
RTDE_OUTPUT_TYPES: dict[str, str] = {
    **dict.fromkeys(_V6, "VECTOR6D"),
    **dict.fromkeys(_D, "DOUBLE"),
    "actual_digital_input_bits": "UINT64",
    "actual_digital_output_bits": "UINT64",
    "robot_mode": "INT32",
    "safety_mode": "INT32",
    "joint_mode": "VECTOR6INT32",
    "actual_tool_accelerometer": "VECTOR3D",
    "runtime_state": "UINT32",
    "robot_status_bits": "UINT32",
    "safety_status_bits": "UINT32",
    "payload": "DOUBLE",  # kg (ur_rtde 1.6's default recipe asks for it and payload_cog)
    "payload_cog": "VECTOR3D",  # m
    **RtdeInputs.OUTPUT_TYPES,
    **{f"output_int_register_{i}": "INT32" for i in range(48)},
    **{f"output_double_register_{i}": "DOUBLE" for i in range(48)},
}
"""Every output the simulator serves, with its RTDE type (ur_rtde's default receive recipe and more)."""

_MAX_HZ = 500.0
_VERSION = (5, 8, 0, 0)


def encode_rtde(packet_type: str, payload: bytes = b"") -> bytes:
    """Frame an RTDE packet: ``uint16 size`` (incl. the 3-byte header), ``uint8 type``, payload."""
    return struct.pack(">HB", len(payload) + 3, ord(packet_type)) + payload


@dataclass(frozen=True)
class _Recipe:
    names: tuple[str, ...]
    period_s: float
    valid: bool


def _values(
    t_s: float, q: tuple[float, ...], pose: tuple[float, ...], s: RobotModeSample
) -> dict[str, object]:
    """The modelled outputs' values (everything else is zero)."""
    runtime = 2 if s.program_running else 4 if s.program_paused else 1
    return {
        "timestamp": t_s,
        "target_q": q,
        "actual_q": q,
        "actual_TCP_pose": pose,
        "target_TCP_pose": pose,
        "speed_scaling": s.speed_scaling,
        "target_speed_fraction": s.target_speed_fraction,
        "robot_mode": s.robot_mode,
        "safety_mode": 1,
        "joint_mode": (253,) * 6,
        "runtime_state": runtime,
        "robot_status_bits": int(s.robot_power_on) | int(s.program_running) << 1,
        "safety_status_bits": 1,
    }


def _pack(name: str, value: object) -> bytes:
    fmt = RTDE_TYPE_FORMATS[RTDE_OUTPUT_TYPES[name]]
    if value is None:
        count = int(fmt[:-1] or 1)
        value = (0,) * count if count > 1 else 0
    vals = value if isinstance(value, tuple) else (value,)
    return struct.pack(">" + fmt, *vals)


class SimUrRtde(LoopbackServer, StartsOnEnter):
    """Loopback RTDE server (outputs only) around the shared arm (context manager).

    Args:
        dh: DH model whose forward kinematics gives the TCP pose (flange).
        arm: The arm's mode (shared with the other ports).
        host: Bind address.
        port: Bind port (0 = a free port).
        moving: Joints follow the real-time stream's path; otherwise they stay at zero.

    Raises:
        OSError: The address cannot be bound.
    """

    def __init__(
        self,
        dh: DHParameters,
        arm: UrArmState,
        *,
        host: str = "127.0.0.1",
        port: int = 0,
        moving: bool = True,
    ) -> None:
        super().__init__(host=host, port=port, name="sim-ur-rtde")
        self.dh = dh
        self.arm = arm
        self.moving = moving
        self.inputs = RtdeInputs()
        self._t0 = time.monotonic()

    def _state(self) -> dict[str, object]:
        t_s = time.monotonic() - self._t0
        q = joint_path(t_s) if self.moving else (0.0,) * 6
        T = fk_dh(self.dh, list(q))
        rv = rotvec_from_matrix(T[:3, :3])
        pose = (float(T[0, 3]), float(T[1, 3]), float(T[2, 3]), float(rv[0]), float(rv[1]), float(rv[2]))
        return {**_values(t_s, q, pose, self.arm.sample()), **self.inputs.outputs()}

    def _serve(self, conn: socket.socket) -> None:
        conn.settimeout(1.0)  # a send waits up to a second for a slow reader
        recipes: list[_Recipe] = []
        inputs: list[tuple[str, ...]] = []
        due: list[float] = []
        started = False
        buf = b""
        while not self.stopping:
            wait_s = 0.2 if not started or not due else max(0.0, min(due) - time.monotonic())
            readable, _, _ = select.select([conn], [], [], min(wait_s, 0.2))
            if readable:
                data = conn.recv(65536)
                if not data:
                    return
                buf += data
                while len(buf) >= 3 and len(buf) >= (size := struct.unpack_from(">H", buf)[0]):
                    if size < 3:
                        return  # not RTDE
                    kind, payload, buf = chr(buf[2]), buf[3:size], buf[size:]
                    reply, started = self._answer(kind, payload, recipes, inputs, started)
                    if kind == "S" and started:
                        due = [time.monotonic()] * len(recipes)
                    if reply:
                        conn.sendall(reply)
            if started:
                now = time.monotonic()
                state: dict[str, object] | None = None
                for i, r in enumerate(recipes):
                    if r.valid and due[i] <= now:
                        state = state or self._state()
                        body = b"".join(_pack(n, state.get(n)) for n in r.names)
                        conn.sendall(encode_rtde("U", struct.pack(">B", i + 1) + body))
                        due[i] = max(due[i] + r.period_s, now)  # late: no burst to catch up

    def _answer(
        self, kind: str, payload: bytes, recipes: list[_Recipe], inputs: list[tuple[str, ...]], started: bool
    ) -> tuple[bytes, bool]:
        """The reply to one client packet and whether data flows afterwards."""
        answers: dict[str, Callable[[], bytes]] = {
            "V": lambda: encode_rtde("V", bytes([len(payload) == 2 and payload == b"\x00\x02"])),
            "v": lambda: encode_rtde("v", struct.pack(">4I", *_VERSION)),
        }
        if kind in answers:
            return answers[kind](), started
        if kind == "I":
            names = _names(payload)
            types = self.inputs.types(names)
            ok = bool(names) and "NOT_FOUND" not in types
            if ok:
                inputs.append(tuple(names))
            return encode_rtde("I", bytes([len(inputs) if ok else 0]) + ",".join(types).encode()), started
        if kind == "U" and payload and 1 <= payload[0] <= len(inputs):
            self.inputs.apply(inputs[payload[0] - 1], payload[1:])  # a package of the wrong size is dropped
            return b"", started
        if kind == "O" and len(payload) >= 8 and not started:
            (hz,) = struct.unpack_from(">d", payload)
            names = _names(payload[8:])
            types = [RTDE_OUTPUT_TYPES.get(n, "NOT_FOUND") for n in names]
            ok = bool(names) and "NOT_FOUND" not in types and math.isfinite(hz) and hz > 0
            recipes.append(_Recipe(tuple(names), 1.0 / min(hz, _MAX_HZ) if ok else 1.0, ok))
            return encode_rtde("O", bytes([len(recipes) if ok else 0]) + ",".join(types).encode()), started
        if kind == "S":
            ok = bool(recipes or inputs) and all(r.valid for r in recipes)
            return encode_rtde("S", bytes([ok])), ok
        if kind == "P":
            return encode_rtde("P", b"\x01"), False
        return b"", started  # unknown or out-of-order packets are ignored


def _names(raw: bytes) -> list[str]:
    """Comma-separated names (empty ones, as after ur_rtde's trailing comma, dropped)."""
    return [n for n in raw.decode("ascii", "replace").split(",") if n]
