"""``robocal sim ur``: the simulated controller on a TCP port for ``robocal ur extract --host`` in another process."""

from __future__ import annotations

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


def test_port_in_use_is_a_device_error(tmp_path: Path) -> None:
    with busy_port() as port:
        r = robocal("sim", "ur", "--port", str(port), cwd=tmp_path, timeout=30)
    assert r.returncode == 3
    assert r.stderr.startswith(f"error: cannot listen on 127.0.0.1:{port} (")
    assert len(r.stderr.strip().splitlines()) == 1


def test_dh_and_model_together_are_refused(tmp_path: Path) -> None:
    r = robocal("sim", "ur", "--dh", "x.yaml", "--model", "ur5e", cwd=tmp_path, timeout=30)
    assert r.returncode == 2
    assert r.stderr.strip() == "error: give either --dh FILE or --model MODEL [--deltas FILE], not both"
