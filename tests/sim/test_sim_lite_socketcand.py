"""``robocal sim lite --interface socketcand`` (the default without vcan): the simulated Lite behind a socketcand
server on 127.0.0.1, reached from other processes by python-can's own ``socketcand`` interface (issue 29)."""

from __future__ import annotations

import json
import socket
import struct
import subprocess
import sys
from pathlib import Path

import can
import pytest

from robocal.backends.robstride.protocol import CommType, Param, make_id, split_id
from robocal.errors import DeviceError, UsageError
from robocal.workflows.sim.job import serve_lite

from .test_sim_lite_cli import sim_lite_offsets

pytestmark = pytest.mark.timeout(240)


@pytest.mark.slow
def test_socketcand_lite_answers_python_can(sim_process, tmp_path: Path) -> None:  # type: ignore[no-untyped-def]
    sim = sim_process(["lite", "--interface", "socketcand", "--port", "0", "--seed", "2"])
    source = sim.info["source"]
    port = int(source.rpartition("=")[2])
    assert source == f"can:socketcand:can0,can1?port={port}"
    assert (
        sim.info["channels"] == f"can0=can0 (ids 11-17), can1=can1 (ids 21-27) on socketcand 127.0.0.1:{port}"
    )
    assert (
        sim.info["python-can"]
        == f"can.Bus(interface='socketcand', channel='can0', host='127.0.0.1', port={port})"
    )
    replies = {}
    for channel, motor in (("can0", 11), ("can1", 27)):
        bus = can.Bus(interface="socketcand", channel=channel, host="127.0.0.1", port=port)
        try:
            bus.send(
                can.Message(
                    arbitration_id=make_id(CommType.PARAM_READ, 0xFD, motor),
                    data=struct.pack("<HHI", Param.VBUS, 0, 0),
                )
            )
            reply = bus.recv(timeout=10.0)
            assert reply is not None
            replies[channel] = (
                split_id(reply.arbitration_id),
                struct.unpack("<f", bytes(reply.data[4:8]))[0],
            )
            assert bus.recv(timeout=0.2) is None  # not its own request back
        finally:
            bus.shutdown()
    assert replies == {
        "can0": ((CommType.PARAM_READ, 11, 0xFD), 24.0),
        "can1": ((CommType.PARAM_READ, 27, 0xFD), 24.0),
    }


def test_busy_socketcand_port_is_a_device_failure() -> None:
    with socket.socket() as taken:
        taken.bind(("127.0.0.1", 0))
        taken.listen(1)
        port = taken.getsockname()[1]
        with (
            pytest.raises(DeviceError, match=rf"^cannot listen on 127\.0\.0\.1:{port} for socketcand: "),
            serve_lite(interface="socketcand", port=port),
        ):
            pass


def test_port_applies_to_socketcand_only() -> None:
    with (
        pytest.raises(UsageError, match=r"^--port applies to --interface socketcand, not udp_multicast$"),
        serve_lite(interface="udp_multicast", port=5),
    ):
        pass


@pytest.mark.skipif(Path("/sys/class/net/vcan0").exists(), reason="vcan0 exists: the default is socketcan")
def test_default_without_vcan_is_socketcand(tmp_path: Path) -> None:
    with serve_lite(port=0, control=str(tmp_path / "control.sock")) as device:
        source, channels = device.lines[:2]
    assert source.startswith("source: can:socketcand:can0,can1?port=")
    assert channels.startswith(
        "channels: can0=can0 (ids 11-17), can1=can1 (ids 21-27) on socketcand 127.0.0.1:"
    )


@pytest.mark.slow
def test_sweep_over_socketcand_matches_sim_lite(tmp_path: Path) -> None:
    """``robocal sweep --source can:socketcand:…`` in another process finds the offsets ``sim:lite`` finds."""
    driver = Path(__file__).with_name("lite_netns_driver.py")
    r = subprocess.run(
        [sys.executable, str(driver), str(tmp_path), "4", "socketcand"],
        capture_output=True,
        text=True,
        timeout=200,
    )
    assert r.returncode == 0, r.stderr[-3000:]
    live = json.loads(r.stdout.strip().splitlines()[-1])
    assert live["source"].startswith("can:socketcand:can0,can1?port=")
    assert live["code"] in (0, 1), live["output"]
    expected = sim_lite_offsets(tmp_path, 4)
    assert list(live["offsets"]) == list(expected)
    for name, value in expected.items():
        assert live["offsets"][name] == pytest.approx(value, abs=1e-3), name
