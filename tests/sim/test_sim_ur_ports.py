"""The simulated UR controller on all its ports: dashboard, primary, secondary, real-time, one arm behind them.

Clients are plain sockets built from the byte layouts (python-urx's real-time 5.9 layout: ``int32`` size 1116,
then 139 big-endian doubles) and robocal's own primary client.
"""

from __future__ import annotations

import socket
import struct
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest
from tests.net import recv_exact

from robocal.backends.sim.ur_arm_state import UrArmState, parse_robot_mode_data
from robocal.backends.sim.ur_realtime import (
    REALTIME_MESSAGE_SIZE,
    SimUrRealtime,
    build_realtime_message,
    joint_path,
)
from robocal.backends.ur_primary import PrimaryClient, iter_subpackages
from robocal.cli.main import main
from robocal.core.dh import fk_dh
from robocal.core.se3 import rotvec_from_matrix
from robocal.core.ur import nominal_dh
from robocal.workflows.sim.job import UR_PORT_OFFSETS, serve_ur

from .conftest import robocal

pytestmark = pytest.mark.timeout(60)

HANG_GUARD_S = 10.0
URX_RT_5_9 = ">i139d"  # python-urx rtstruct5_9: size, then 139 doubles


def _realtime(sock: socket.socket) -> tuple[float, ...]:
    header = recv_exact(sock, 4)
    (size,) = struct.unpack(">i", header)
    assert size == REALTIME_MESSAGE_SIZE == 1116
    return struct.unpack(URX_RT_5_9, header + recv_exact(sock, size - 4))[1:]


def test_realtime_message_fields_where_python_urx_reads_them() -> None:
    dh = nominal_dh("ur5e")
    q = (0.1, -1.2, 1.0, -0.5, 1.5, 0.3)
    v = struct.unpack(URX_RT_5_9, build_realtime_message(dh, 12.5, q, robot_mode=5, program_running=True))
    assert v[0] == 1116
    d = v[1:]
    assert d[0] == 12.5  # Time
    assert d[1:7] == q and d[31:37] == q  # q_target, q_actual
    T = fk_dh(dh, list(q))
    pose = np.r_[T[:3, 3], rotvec_from_matrix(T[:3, :3])]
    np.testing.assert_allclose(d[73:79], pose, atol=1e-12)  # Tool_vector_target: python-urx's TCP pose
    assert d[55:61] == d[73:79]  # Tool_vector_actual
    assert (d[94], d[101], d[131], d[138]) == (5.0, 1.0, 2.0, 1.0)  # robot, safety mode; program; safety status
    assert d[95:101] == (253.0,) * 6


def test_realtime_server_streams_the_arm_and_follows_its_mode() -> None:
    dh = nominal_dh("ur10e")
    arm = UrArmState()
    with SimUrRealtime(dh, arm) as rt, socket.create_connection(rt.address, timeout=HANG_GUARD_S) as sock:
        first = _realtime(sock)
        second = _realtime(sock)
        assert second[0] > first[0]  # controller time moves on
        assert first[94] == 7.0
        q = joint_path(first[0])
        np.testing.assert_allclose(first[31:37], q, atol=1e-12)
        arm.power_off()
        for _ in range(5000):  # bounded: at 500 Hz the change shows within a few messages
            if _realtime(sock)[94] == 3.0:
                break
        else:
            raise AssertionError("robot mode never became 3 (POWER_OFF)")


@pytest.fixture
def all_ports() -> Iterator[dict[str, tuple[str, int]]]:
    with serve_ur(base_port=0, model="ur5e") as device:
        yield {
            k: (h, int(p))
            for k, _, v in (line.partition(": ") for line in device.lines)
            if k in ("dashboard", "secondary", "real-time", "rtde", "address")
            for h, _, p in [v.rpartition(":")]
        }


def test_all_ports_share_one_arm(all_ports) -> None:
    assert set(all_ports) == {"dashboard", "secondary", "real-time", "rtde", "address"}
    assert len({p for _, p in all_ports.values()}) == 5
    with socket.create_connection(all_ports["dashboard"], timeout=HANG_GUARD_S) as dash:
        f = dash.makefile("rw", newline="\n")
        assert f.readline() == "Connected: Universal Robots Dashboard Server\n"
        f.write("get robot model\npower off\n")
        f.flush()
        assert (f.readline(), f.readline()) == ("UR5\n", "Powering off\n")
    for port in ("address", "secondary"):
        with PrimaryClient(*all_ports[port], timeout_s=HANG_GUARD_S) as client:
            assert client.read_message()[0] == 20  # the version message first, at once (python-urx waits 0.5 s)
            while (msg := client.read_message())[0] != 16:
                pass
            sub_type, sub = next(iter_subpackages(msg[1]))
            assert sub_type == 0 and parse_robot_mode_data(sub).robot_mode == 3
    with socket.create_connection(all_ports["real-time"], timeout=HANG_GUARD_S) as rt:
        assert _realtime(rt)[94] == 3.0


def test_port_offsets_are_the_controllers() -> None:
    assert [29999 + off for _, off in UR_PORT_OFFSETS] == [29999, 30001, 30002, 30003, 30004]


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["--port", "0", "--base-port", "0"], "give one of --port, --standard-ports and --base-port, not --port and --base-port"),
        (["--standard-ports", "--base-port", "0"], "give one of --port, --standard-ports and --base-port, not --standard-ports and --base-port"),
        (["--base-port", "65532"], "--base-port 65532: expected 0 (any free ports) or 1..65530"),
        (["--base-port", "-1"], "--base-port -1: expected 0 (any free ports) or 1..65530"),
    ],
)  # fmt: skip
def test_port_choice_refusals(args: list[str], message: str, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["sim", "ur", *args]) == 2
    assert capsys.readouterr().err.strip() == f"error: {message}"


@pytest.mark.slow
def test_standalone_controller_with_base_port_serves_every_port(sim_process, tmp_path: Path) -> None:
    sim = sim_process(["ur", "--base-port", "0"], until="address")
    assert set(sim.info) >= {"dashboard", "secondary", "real-time", "rtde", "address"}
    host, _, port = sim.info["dashboard"].rpartition(":")
    with socket.create_connection((host, int(port)), timeout=HANG_GUARD_S) as dash:
        f = dash.makefile("rw", newline="\n")
        assert f.readline() == "Connected: Universal Robots Dashboard Server\n"
        f.write("robotmode\nget robot model\n")
        f.flush()
        assert (f.readline(), f.readline()) == ("Robotmode: RUNNING\n", "UR10\n")
    host, _, port = sim.info["secondary"].rpartition(":")
    ex = robocal("ur", "extract", "--host", host, "--port", port, "--out", "ex.yaml", cwd=tmp_path)
    assert ex.returncode == 0, ex.stderr
    code, err = sim.stop()
    assert code == 0 and "simulator stopped" in err
