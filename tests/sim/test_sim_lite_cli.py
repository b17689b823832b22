"""``robocal sim lite`` on a CAN interface other processes share: ``robocal sweep --source can:udp_multicast:…``
in another process recovers the same offsets as ``--source sim:lite``.

The udp_multicast frames must not leave the machine, so the two processes run in a private network namespace
(``unshare --net``) whose loopback carries the multicast route; without root or ``unshare`` the test is skipped.
"""

from __future__ import annotations

import json
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from robocal.backends.sim.lite import lite_urdf_text

from .conftest import robocal

pytestmark = pytest.mark.timeout(180)

NETNS_SETUP = "ip link set lo up && ip link set lo multicast on && ip route add 239.0.0.0/8 dev lo"


def _netns_available() -> str | None:
    if shutil.which("unshare") is None or shutil.which("ip") is None:
        return "unshare or ip is not installed"
    r = subprocess.run(["unshare", "--net", "sh", "-c", NETNS_SETUP], capture_output=True, text=True)
    return None if r.returncode == 0 else f"cannot make a private network namespace: {r.stderr.strip()}"


@pytest.mark.slow
def test_sweep_over_udp_multicast_matches_sim_lite(tmp_path: Path) -> None:
    reason = _netns_available()
    if reason:
        pytest.skip(reason)
    try:
        import msgpack  # noqa: F401
    except ImportError:
        pytest.skip("msgpack (python-can's udp_multicast) is not installed")
    driver = Path(__file__).with_name("lite_netns_driver.py")
    r = subprocess.run(
        [
            "unshare",
            "--net",
            "sh",
            "-c",
            f'{NETNS_SETUP} && exec "$0" "$@"',
            sys.executable,
            str(driver),
            str(tmp_path),
            "4",
        ],
        capture_output=True,
        text=True,
        timeout=150,
    )
    assert r.returncode == 0, r.stderr[-3000:]
    live = json.loads(r.stdout.strip().splitlines()[-1])
    assert live["source"] == "can:udp_multicast:239.74.163.2,239.74.163.3"
    assert live["code"] in (0, 1), live["output"]
    expected = sim_lite_offsets(tmp_path, 4)
    assert list(live["offsets"]) == list(expected)
    for name, value in expected.items():
        assert live["offsets"][name] == pytest.approx(value, abs=1e-3), name


def sim_lite_offsets(tmp_path: Path, seed: int) -> dict[str, float]:
    """The homing offsets ``robocal sweep --source sim:lite?seed=N`` finds (the in-process reference)."""
    (tmp_path / "ref").mkdir()
    (tmp_path / "ref/lite.urdf").write_text(lite_urdf_text())
    ref = robocal(
        "sweep",
        "--urdf",
        "lite.urdf",
        "--source",
        f"sim:lite?seed={seed}",
        "--out",
        "cal.yaml",
        "--report",
        "report.json",
        cwd=tmp_path / "ref",
    )
    assert ref.returncode in (0, 1), ref.stderr
    return {
        n: j["homing_offset"] for n, j in json.loads((tmp_path / "ref/report.json").read_text())["joints"].items()
    }


def test_socketcan_without_a_vcan_interface_is_a_clear_error(tmp_path: Path) -> None:
    r = robocal(
        "sim",
        "lite",
        "--interface",
        "socketcan",
        "--channel",
        "robocalnone0,robocalnone1",
        "--no-view",
        cwd=tmp_path,
        timeout=30,
    )
    assert r.returncode == 2
    assert r.stderr.strip().splitlines() == [
        "error: no CAN interface robocalnone0, robocalnone1: create it (ip link add robocalnone0 type vcan && "
        "ip link set robocalnone0 up) or use --interface socketcand"
    ]


@pytest.mark.slow
def test_lite_needs_two_different_channels(tmp_path: Path) -> None:
    r = robocal(
        "sim",
        "lite",
        "--interface",
        "udp_multicast",
        "--channel",
        "239.1.1.1,239.1.1.1",
        "--no-view",
        cwd=tmp_path,
        timeout=30,
    )
    assert r.returncode == 2
    assert "expected two different channels, for can0 and can1" in r.stderr
