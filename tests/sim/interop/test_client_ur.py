"""ur_rtde 1.6.5 (RTDE receive, dashboard client) and python-urx 0.11, unchanged, each in its own environment,
against ``robocal sim ur --standard-ports`` in another process (issue 29).

Both clients use a controller's fixed ports (29999, 30002-30004), so each test serves them on an address of its
own in 127.0.0.0/8, where nothing else on the machine listens on those ports.
"""

from __future__ import annotations

import os
import random

import numpy as np
import pytest

from robocal.backends.sim.ur_realtime import joint_path
from robocal.core.dh import fk_dh
from robocal.core.se3 import rotvec_from_matrix
from robocal.core.ur import TEST_SET_3_DELTAS, nominal_dh

from .conftest import client_env_python, run_client

pytestmark = [pytest.mark.interop, pytest.mark.timeout(300)]

DH = nominal_dh("ur10e") + TEST_SET_3_DELTAS
"""The DH of the default simulated controller (a UR10e with the UR demo's factory calibration)."""


def own_loopback() -> str:
    """An address in 127.0.0.0/8 for this test alone (not 127.0.0.1, where a person's simulator may run)."""
    rng = random.Random(os.getpid() ^ random.getrandbits(32))
    return f"127.{rng.randint(20, 250)}.{rng.randint(1, 250)}.{rng.randint(1, 250)}"



def flange_pose(q: list[float]) -> list[float]:
    """The TCP pose the simulated controller reports for ``q``: flange position and rotation vector."""
    T = fk_dh(DH, q)
    return [*map(float, T[:3, 3]), *map(float, rotvec_from_matrix(T[:3, :3]))]


@pytest.mark.slow
def test_ur_rtde_receive_and_dashboard(sim_process) -> None:  # type: ignore[no-untyped-def]
    python = client_env_python("ur_rtde")
    host = own_loopback()
    sim = sim_process(["ur", "--standard-ports", "--host", host], until="address")
    assert sim.info["rtde"] == f"{host}:30004" and sim.info["dashboard"] == f"{host}:29999"
    got = run_client(python, "ur_rtde_client.py", {"host": host})
    assert got["connected"] is True
    times = [s["t"] for s in got["samples"]]
    assert times == sorted(times) and times[-1] > times[0]
    for s in got["samples"]:  # joints and pose of one package belong together
        np.testing.assert_allclose(s["q"], joint_path(s["t"]), atol=1e-12)
        np.testing.assert_allclose(s["target_q"], s["q"], atol=0)
        np.testing.assert_allclose(s["tcp"], flange_pose(s["q"]), atol=1e-9)
    assert (got["robot_mode"], got["safety_mode"], got["runtime_state"]) == (7, 1, 1)
    assert got["speed_scaling"] == 1.0 and got["payload"] == 0.0
    assert got["dashboard"] == {
        "connected": True,
        "robotmode": "Robotmode: RUNNING",
        "polyscope": "5.8.0.0",
        "serial": "20235500001",
        "safetystatus": "Safetystatus: NORMAL",
        "program_state": "STOPPED <unnamed>",
        "remote": True,
    }
    # the dashboard's power commands change the mode every port reports
    assert got["after_power_off"] == {"dashboard": "Robotmode: POWER_OFF", "rtde": 3}
    assert got["after_power_on"] == {"dashboard": "Robotmode: IDLE", "rtde": 5}
    assert got["after_brake_release"] == {"dashboard": "Robotmode: RUNNING", "rtde": 7}


@pytest.mark.slow
def test_urx_reads_joints_mode_and_tcp(sim_process) -> None:  # type: ignore[no-untyped-def]
    python = client_env_python("urx")
    host = own_loopback()
    sim_process(["ur", "--standard-ports", "--host", host], until="address")
    got = run_client(python, "urx_client.py", {"host": host})
    mode = got["robot_mode"]
    assert mode["size"] == 47 and mode["robotMode"] == 7  # a powered, running 5.x arm
    assert [mode[k] for k in ("isRobotConnected", "isRealRobotEnabled", "isPowerOnRobot")] == [True] * 3
    assert [mode[k] for k in ("isEmergencyStopped", "isSecurityStopped", "isProgramRunning")] == [False] * 3
    # urx 0.11 knows RobotModeData of 38 (3.0) and 46 bytes (3.2) only: for the 47 bytes of 5.x it keeps firmware
    # "version (0, 0)" and waits for the pre-3.0 running mode 0, so it reports a running 5.x arm as not running
    # (as it does with a real 5.x controller; the GitHub python-urx knows 47)
    assert got["running"] is False and got["program_running"] is False
    joints = got["secondary_joints"]
    assert joints["size"] == 251
    for i in range(6):
        assert joints[f"q_actual{i}"] == joints[f"q_target{i}"] and abs(joints[f"q_actual{i}"]) <= 1.5
        assert (joints[f"V_actual{i}"], joints[f"T_motor{i}"], joints[f"jointMode{i}"]) == (48.0, 30.0, 253)
    assert len(got["getj"]) == 6 and all(abs(q) <= 1.5 for q in got["getj"])
    # the real-time stream: joints on the simulator's path at the controller time, the TCP pose from the DH
    np.testing.assert_allclose(got["rt_q_actual"], joint_path(got["rt_ctrl_time"]), atol=1e-12)
    np.testing.assert_allclose(got["rt_tcp"], flange_pose(got["rt_q_actual"]), atol=1e-9)
    assert abs(mode["timestamp"] / 1e6 - got["rt_ctrl_time"]) < 30.0  # one clock (µs since start), read apart
    # urx 0.11's getl calls PoseVector.tolist(), which the math3d it installs (4.0) no longer has
    assert got["getl"] == "AttributeError: 'PoseVector' object has no attribute 'tolist'"


def rtde_outputs(host: str, names: list[str]) -> tuple[object, ...]:
    """One data package of ``names`` read over a plain RTDE socket (robocal's side of the protocol)."""
    import socket
    import struct

    from robocal.backends.sim.ur_rtde import RTDE_OUTPUT_TYPES, RTDE_TYPE_FORMATS, encode_rtde

    def packet(sock: socket.socket) -> tuple[str, bytes]:
        head = b""
        while len(head) < 3:
            head += sock.recv(3 - len(head))
        size, kind = struct.unpack(">HB", head)
        body = b""
        while len(body) < size - 3:
            body += sock.recv(size - 3 - len(body))
        return chr(kind), body

    with socket.create_connection((host, 30004), timeout=20) as sock:
        sock.sendall(encode_rtde("V", struct.pack(">H", 2)))
        assert packet(sock) == ("V", b"\x01")
        sock.sendall(encode_rtde("O", struct.pack(">d", 10.0) + ",".join(names).encode()))
        kind, body = packet(sock)
        assert kind == "O" and body[0] == 1, body
        sock.sendall(encode_rtde("S"))
        assert packet(sock) == ("S", b"\x01")
        kind, body = packet(sock)
        assert kind == "U" and body[0] == 1
        fmt = ">" + "".join(RTDE_TYPE_FORMATS[RTDE_OUTPUT_TYPES[n]] for n in names)
        return struct.unpack(fmt, body[1:])


@pytest.mark.slow
def test_ur_rtde_io_sets_outputs_registers_and_slider(sim_process) -> None:  # type: ignore[no-untyped-def]
    python = client_env_python("ur_rtde")
    host = own_loopback()
    sim_process(["ur", "--standard-ports", "--host", host], until="address")
    got = run_client(python, "ur_rtde_io_client.py", {"host": host})
    assert got["set"] == [True] * 6
    assert got["digital_output_bits"] == (1 << 2) | (1 << 17)  # standard DO 2; tool DO 1 is bit 16 + 1
    assert got["digital_out_2"] is True
    assert (got["speed_fraction"], got["analog_output_1"]) == (0.5, 0.25)
    # the input registers stay on the controller for any RTDE client to read
    assert rtde_outputs(
        host, ["input_int_register_18", "input_double_register_19", "input_int_register_17"]
    ) == (
        42,
        1.5,
        0,
    )


def test_rtde_inputs_follow_their_masks() -> None:
    """In process: an input package changes only what its masks select; registers read back as outputs."""
    import struct

    from robocal.backends.sim.ur_rtde_inputs import RtdeInputs

    inputs = RtdeInputs()
    names = (
        "standard_digital_output_mask",
        "standard_digital_output",
        "speed_slider_mask",
        "speed_slider_fraction",
    )
    assert inputs.types([*names, "bogus"]) == ["UINT8", "UINT8", "UINT32", "DOUBLE", "NOT_FOUND"]
    assert inputs.apply(
        names, struct.pack(">BBId", 0b0110, 0b1110, 0, 0.3)
    )  # DO 1, 2 on; DO 3 not in the mask
    assert inputs.outputs()["actual_digital_output_bits"] == 0b0110
    assert inputs.outputs()["target_speed_fraction"] == 1.0  # slider mask 0: unchanged
    assert inputs.apply(names, struct.pack(">BBId", 0b0010, 0, 1, 1.7))  # DO 1 off; slider clipped to 1
    assert (inputs.outputs()["actual_digital_output_bits"], inputs.outputs()["target_speed_fraction"]) == (
        0b0100,
        1.0,
    )
    assert inputs.apply(("input_int_register_20",), struct.pack(">i", -7))
    assert inputs.outputs()["input_int_register_20"] == -7
    assert not inputs.apply(("input_int_register_20",), b"\x00")  # wrong size: dropped
