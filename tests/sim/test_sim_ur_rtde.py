"""The simulated RTDE server (30004) driven as ur_rtde's receive interface drives it, with raw sockets.

The byte strings are the exchanges of the RTDE protocol (version 2) as ur_rtde and URCL send and read them.
"""

from __future__ import annotations

import socket
import struct
from collections.abc import Iterator

import numpy as np
import pytest
from tests.net import recv_exact

from robocal.backends.sim.ur_arm_state import UrArmState
from robocal.backends.sim.ur_realtime import joint_path
from robocal.backends.sim.ur_rtde import RTDE_OUTPUT_TYPES, RTDE_TYPE_FORMATS, SimUrRtde
from robocal.core.dh import fk_dh
from robocal.core.ur import nominal_dh

pytestmark = pytest.mark.timeout(60)

UR_RTDE_DEFAULT_RECIPE = [
    "timestamp",
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
    "actual_digital_input_bits",
    "joint_temperatures",
    "actual_execution_time",
    "robot_mode",
    "joint_mode",
    "safety_mode",
    "actual_tool_accelerometer",
    "speed_scaling",
    "target_speed_fraction",
    "actual_momentum",
    "actual_main_voltage",
    "actual_robot_voltage",
    "actual_robot_current",
    "actual_joint_voltage",
    "actual_digital_output_bits",
    "runtime_state",
    "standard_analog_input0",
    "standard_analog_input1",
    "standard_analog_output0",
    "standard_analog_output1",
    "robot_status_bits",
    "safety_status_bits",
    "output_int_register_2",
    "output_int_register_12",
    "output_double_register_12",
]
"""Names of ur_rtde's RTDEReceiveInterface default recipe (a representative part of its registers)."""

EXPECTED_TYPES = {
    "timestamp": "DOUBLE", "actual_q": "VECTOR6D", "actual_digital_input_bits": "UINT64", "robot_mode": "INT32",
    "joint_mode": "VECTOR6INT32", "actual_tool_accelerometer": "VECTOR3D", "runtime_state": "UINT32",
    "output_int_register_12": "INT32", "output_double_register_12": "DOUBLE",
}  # fmt: skip


def _packet(sock: socket.socket) -> tuple[int, bytes]:
    size, kind = struct.unpack(">HB", recv_exact(sock, 3))
    return kind, recv_exact(sock, size - 3)


@pytest.fixture
def rtde() -> Iterator[tuple[UrArmState, socket.socket]]:
    arm = UrArmState()
    with SimUrRtde(nominal_dh("ur5e"), arm) as server:
        sock = socket.create_connection(server.address, timeout=10)
        yield arm, sock
        sock.close()


def test_version_exchanges_match_the_protocol_bytes(rtde) -> None:
    _, sock = rtde
    sock.sendall(bytes.fromhex("0005560002"))
    assert recv_exact(sock, 4) == bytes.fromhex("00045601")
    sock.sendall(bytes.fromhex("000376"))
    assert recv_exact(sock, 19) == bytes.fromhex("001376") + struct.pack(">4I", 5, 8, 0, 0)  # 5.8.0.0
    sock.sendall(bytes.fromhex("0005560009"))  # a version it does not speak
    assert recv_exact(sock, 4) == bytes.fromhex("00045600")


def test_setup_outputs_with_ur_rtdes_trailing_comma(rtde) -> None:
    _, sock = rtde
    sock.sendall(bytes.fromhex("001E4F407F40000000000074696D657374616D702C61637475616C5F712C"))
    assert recv_exact(sock, 19) == bytes.fromhex("00134F01444F55424C452C564543544F523644")


def test_ur_rtde_receive_sequence_streams_the_arm(rtde) -> None:
    arm, sock = rtde
    sock.sendall(bytes.fromhex("0005560002") + bytes.fromhex("000376"))
    assert [_packet(sock)[0] for _ in range(2)] == [ord("V"), ord("v")]
    names = ",".join(UR_RTDE_DEFAULT_RECIPE) + ","
    body = struct.pack(">d", 500.0) + names.encode()
    sock.sendall(struct.pack(">HB", len(body) + 3, ord("O")) + body)
    kind, reply = _packet(sock)
    assert kind == ord("O") and reply[0] == 1
    types = reply[1:].decode().split(",")
    assert len(types) == len(UR_RTDE_DEFAULT_RECIPE) and "NOT_FOUND" not in types
    for name, t in EXPECTED_TYPES.items():
        assert types[UR_RTDE_DEFAULT_RECIPE.index(name)] == t
    sock.sendall(bytes.fromhex("000353"))
    assert _packet(sock) == (ord("S"), b"\x01")
    fmt = ">B" + "".join(RTDE_TYPE_FORMATS[RTDE_OUTPUT_TYPES[n]] for n in UR_RTDE_DEFAULT_RECIPE)
    kind, data = _packet(sock)
    assert kind == ord("U") and len(data) == struct.calcsize(fmt)
    values = struct.unpack(fmt, data)
    assert values[0] == 1  # recipe id
    flat = dict(zip(["recipe", *_expand(UR_RTDE_DEFAULT_RECIPE)], values, strict=True))
    t = flat["timestamp"]
    q = [flat[f"actual_q[{i}]"] for i in range(6)]
    np.testing.assert_allclose(q, joint_path(t), atol=1e-12)
    T = fk_dh(nominal_dh("ur5e"), q)
    np.testing.assert_allclose([flat[f"actual_TCP_pose[{i}]"] for i in range(3)], T[:3, 3], atol=1e-12)
    assert (flat["robot_mode"], flat["safety_mode"], flat["runtime_state"]) == (7, 1, 1)
    assert flat["speed_scaling"] == 1.0 and flat["robot_status_bits"] == 1
    arm.power_off()
    for _ in range(5000):  # bounded: at 500 Hz the change shows within a few packages
        kind, data = _packet(sock)
        if struct.unpack(fmt, data)[list(flat).index("robot_mode")] == 3:
            break
    else:
        raise AssertionError("robot_mode never became 3 (POWER_OFF)")
    sock.sendall(bytes.fromhex("000350"))
    while (p := _packet(sock))[0] == ord("U"):
        pass
    assert p == (ord("P"), b"\x01")


def test_unknown_output_is_not_found_and_start_is_refused(rtde) -> None:
    _, sock = rtde
    body = struct.pack(">d", 125.0) + b"actual_q,no_such_output"
    sock.sendall(struct.pack(">HB", len(body) + 3, ord("O")) + body)
    assert _packet(sock) == (ord("O"), b"\x00VECTOR6D,NOT_FOUND")
    sock.sendall(bytes.fromhex("000353"))
    assert _packet(sock) == (ord("S"), b"\x00")


def _expand(names: list[str]) -> list[str]:
    out: list[str] = []
    for n in names:
        count = {"VECTOR6D": 6, "VECTOR6INT32": 6, "VECTOR3D": 3}.get(RTDE_OUTPUT_TYPES[n], 1)
        out += [n] if count == 1 else [f"{n}[{i}]" for i in range(count)]
    return out
