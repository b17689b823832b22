"""``robocal sim ur``: the simulated controller on a TCP port for ``robocal ur extract --host`` in another process."""

from __future__ import annotations

import contextlib
import os
import socket
import time
from pathlib import Path

import pytest
from tests.net import busy_port

from .conftest import robocal

pytestmark = pytest.mark.timeout(90)


@pytest.mark.slow
def test_extract_from_the_standalone_controller_equals_offline_correction(
    sim_process, tmp_path: Path
) -> None:
    sim = sim_process(["ur", "--port", "0", "--model", "ur10e"], until="address")
    host, _, port = sim.info["address"].rpartition(":")
    assert host == "127.0.0.1"
    ex = robocal("ur", "extract", "--host", host, "--port", port, "--out", "ex.yaml", cwd=tmp_path)
    assert ex.returncode == 0, ex.stderr
    ref = robocal("ur", "correct", "--model", "ur10e", "--out", "ref.yaml", cwd=tmp_path)
    assert ref.returncode == 0, ref.stderr
    assert (tmp_path / "ex.yaml").read_bytes() == (tmp_path / "ref.yaml").read_bytes()
    assert "hash: calib_5119701370761913513" in ex.stdout
    # a second client while the controller keeps running (state lasts for the process)
    again = robocal("ur", "extract", "--host", host, "--port", port, "--out", "again.yaml", cwd=tmp_path)
    assert again.returncode == 0
    code, err = sim.stop()
    assert code == 0 and "simulator stopped" in err


@pytest.mark.slow
def test_default_controller_is_a_calibrated_ur10e(sim_process, tmp_path: Path) -> None:
    sim = sim_process(["ur", "--port", "0"], until="address")
    host, _, port = sim.info["address"].rpartition(":")
    ex = robocal("ur", "extract", "--host", host, "--port", port, "--out", "ex.yaml", cwd=tmp_path)
    assert ex.returncode == 0, ex.stderr
    assert "deviation from nominal ur10e: " in ex.stdout
    assert "deviation from nominal ur10e: 0.000 mm" not in ex.stdout


@pytest.mark.slow
def test_port_in_use_is_a_device_error(tmp_path: Path) -> None:
    with busy_port() as port:
        r = robocal("sim", "ur", "--port", str(port), cwd=tmp_path, timeout=30)
    assert r.returncode == 3
    assert r.stderr.startswith(f"error: cannot listen on 127.0.0.1:{port} (")
    assert len(r.stderr.strip().splitlines()) == 1


@pytest.mark.slow
def test_dh_and_model_together_are_refused(tmp_path: Path) -> None:
    r = robocal("sim", "ur", "--dh", "x.yaml", "--model", "ur5e", cwd=tmp_path, timeout=30)
    assert r.returncode == 2
    assert r.stderr.strip() == "error: give either --dh FILE or --model MODEL [--deltas FILE], not both"


def _threads_and_sockets(pid: int) -> tuple[int, int]:
    """(threads, open sockets) of a process, from /proc."""
    threads = len(os.listdir(f"/proc/{pid}/task"))
    sockets = 0
    for fd in os.listdir(f"/proc/{pid}/fd"):
        with contextlib.suppress(OSError):  # closed meanwhile
            sockets += os.readlink(f"/proc/{pid}/fd/{fd}").startswith("socket:")
    return threads, sockets


@pytest.mark.slow
@pytest.mark.timeout(300)
@pytest.mark.skipif(not Path("/proc/self/task").exists(), reason="reads threads and sockets from /proc")
def test_finished_connections_are_released(sim_process) -> None:
    """2000 clients connect and hang up (half after reading, half at once): the controller's threads and sockets
    return to what it had before, and it still serves."""
    sim = sim_process(["ur", "--port", "0"], until="address")
    host, _, port = sim.info["address"].rpartition(":")
    pid = sim.proc.pid
    baseline = _threads_and_sockets(pid)
    for i in range(2000):
        with socket.create_connection((host, int(port)), timeout=60) as s:
            if i % 2:
                assert len(s.recv(16)) > 0
    deadline = time.monotonic() + 60
    while _threads_and_sockets(pid) != baseline:
        assert time.monotonic() < deadline, f"still {_threads_and_sockets(pid)}, baseline {baseline}"
        time.sleep(0.05)
    with socket.create_connection((host, int(port)), timeout=60) as s, s.makefile("rb") as f:
        assert f.read(5)[4] == 20  # the version message first
    code, _ = sim.stop()
    assert code == 0


def test_controller_keeps_no_finished_connection() -> None:
    """The controller object drops each finished connection (its socket and thread), whether the client read or
    hung up at once; before, every one stayed in its lists for the life of the process (+5.8 MB per 2000)."""
    import threading

    from robocal.backends.sim.ur_controller import SimUrController
    from robocal.core.ur import nominal_dh

    sim = SimUrController(nominal_dh("ur10e")).start()
    try:
        host, port = sim.address
        for i in range(300):
            with socket.create_connection((host, port), timeout=60) as s:
                if i % 2:
                    assert len(s.recv(16)) > 0
        deadline = time.monotonic() + 60
        while sim.open_connections or len(sim._threads) != 1:
            assert time.monotonic() < deadline, (sim.open_connections, len(sim._threads))
            time.sleep(0.02)
        assert sim.connections == 300
        assert [t.name for t in threading.enumerate() if t.name == "sim-ur-client"] == []
    finally:
        sim.stop()
