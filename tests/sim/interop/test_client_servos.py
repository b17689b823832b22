"""Third-party servo clients, unchanged, each in its own environment, against ``robocal sim`` on a pseudo-terminal
(issue 29): dynamixel-sdk 4.1 (reads, Bulk Read, Fast Sync Read, Fast Bulk Read) on the Koch arm, the PyPI
``st3215`` client (reads, set-middle) and ``feetech-cli`` (scan, selftest, set-zero) on the SO-101 arm. Each test
compares what the client got with the simulator's own state."""

from __future__ import annotations

import os
import subprocess

import pytest

from robocal.backends.sim.control import SimControl

from .client_envs import CLIENT_ENVS
from .conftest import client_env_python, run_client

pytestmark = [pytest.mark.interop, pytest.mark.timeout(300)]

XL430_W250, XL330_M288 = 1060, 1200
"""Model numbers (ROBOTIS e-Manual)."""



def readings(control: str) -> dict[int, dict]:
    """Servo id → the simulator's view of it (reading, Homing_Offset, torque, …)."""
    with SimControl(control) as ctl:
        return {j["id"]: j for j in ctl.state().values()}


def test_every_client_is_pinned() -> None:
    """Each client environment names exact versions (a new release cannot change what the tests run)."""
    for name, env in CLIENT_ENVS.items():
        assert env.requirements and all("==" in r for r in env.requirements), name
    assert CLIENT_ENVS["dynamixel_sdk"].requirements == ("dynamixel-sdk==4.1.0",)


@pytest.mark.slow
def test_dynamixel_sdk_4_reads_bulk_and_fast_reads(sim_process) -> None:  # type: ignore[no-untyped-def]
    python = client_env_python("dynamixel_sdk")
    sim = sim_process(["koch_follower"])
    ids = [1, 2, 3, 4, 5, 6]
    got = run_client(
        python, "dynamixel_sdk_client.py", {"port": sim.info["port"], "baudrate": 1_000_000, "ids": ids}
    )
    truth = {i: int(s["reading"]) for i, s in readings(sim.info["control"]).items()}
    assert got["models"] == {str(i): [XL430_W250 if i <= 2 else XL330_M288, 0] for i in ids}
    for i in ids:
        e = got["eeprom"][str(i)]
        assert (e["Status_Return_Level"], e["PWM_Limit"]) == (2, 885)  # factory values
        assert e["Current_Limit"] == (
            1750 if i > 2 else 0
        )  # XL330-M288's; the XL430 has no current limit item
        assert e["Present_Position"] == truth[i]
    # Bulk Read: a different item of each servo; Fast Bulk Read: the same in one combined status packet
    expected_bulk = {"1": truth[1], "2": XL430_W250, "3": 2}
    assert got["bulk"] == expected_bulk and got["fast_bulk"] == expected_bulk
    assert got["fast_sync"] == got["sync"] == {str(i): truth[i] for i in ids}


@pytest.mark.slow
def test_st3215_reads_and_defines_the_middle(sim_process) -> None:  # type: ignore[no-untyped-def]
    python = client_env_python("st3215")
    sim = sim_process(["so101_follower"])
    before = readings(sim.info["control"])
    got = run_client(
        python, "st3215_client.py", {"port": sim.info["port"], "ids": [1, 2, 3, 4, 5, 6], "middle": 3}
    )
    assert got["ping"] == {str(i): True for i in range(1, 7)} and got["ping_absent"] is False
    for i in range(1, 7):
        r = got["read"][str(i)]
        assert r == {
            "position": int(before[i]["reading"]),
            "voltage": 7.4,
            "temperature": 25,
            "mode": 0,
            "correction": 0,
            "moving": False,
        }
    # set middle (Torque_Enable = 128): the present position becomes 2048 through Homing_Offset; torque stays off
    assert got["define_middle"] is True
    offset = int(before[3]["reading"]) - 2048
    assert got["after_middle"] == {"position": 2048, "correction": offset}
    after = readings(sim.info["control"])
    assert after[3]["Homing_Offset"] == offset and after[3]["reading"] == 2048 and after[3]["torque"] is False


@pytest.mark.slow
def test_feetech_cli_scan_selftest_and_set_zero(sim_process) -> None:  # type: ignore[no-untyped-def]
    python = client_env_python("feetech_cli")
    sim = sim_process(["so101_follower"])
    before = readings(sim.info["control"])

    def feetech(*args: str) -> str:
        # --timeout is the command line's own serial read timeout (default 0.05 s), for a loaded machine
        r = subprocess.run(
            [
                str(python.parent / "feetech"),
                "-p",
                sim.info["port"],
                "-b",
                "1000000",
                "--timeout",
                "0.5",
                *args,
            ],
            capture_output=True,
            text=True,
            timeout=180,
            env=dict(os.environ, PYTHONNOUSERSITE="1", NO_COLOR="1"),
        )
        assert r.returncode == 0, r.stdout[-3000:] + r.stderr[-2000:]
        return r.stdout

    scan = feetech("scan")
    assert "Found 6 servo(s)" in scan
    for i in range(1, 7):
        assert f"id   {i}  model   777  position  {int(before[i]['reading']):>4}" in scan
    test = feetech("selftest", "1")
    for check in (
        "torque limit above zero: 1000",
        "max torque limit above zero: 1000",
        "supply voltage present: 7.4 V",
        "not overheating: 25 C of 70 C",
    ):
        assert check in test
    assert "FAIL" not in test and "PASS: 5 of 5 commanded moves reached their target." in test
    after = readings(sim.info["control"])
    assert after[1]["reading"] == before[1]["reading"] and after[1]["torque"] is False  # left as it was found
    feetech("set-zero", "2", "-y")
    zeroed = readings(sim.info["control"])[2]
    assert zeroed["reading"] == 2048 and zeroed["Homing_Offset"] == int(before[2]["reading"]) - 2048
