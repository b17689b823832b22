"""The PyPI ``damiao-motor`` client (1.0.6, jia-xie/python-damiao-driver), unchanged, in its own environment, drives
the simulated OpenArm's J5 through the socketcand server over a real loopback TCP socket (issue 31)."""

from __future__ import annotations

import json
import os

import pytest

from robocal.backends.damiao.openarm import SimOpenArm
from robocal.backends.damiao.tables import State
from robocal.backends.sim.socketcand import SocketcandServer

from .conftest import client_env_python, run_client

pytestmark = [pytest.mark.interop, pytest.mark.timeout(300)]


def test_pypi_damiao_motor_client_over_socketcand() -> None:
    python = client_env_python("damiao_motor")
    channel = f"pypi-damiao-{os.getpid()}"
    arm = SimOpenArm(channel, zeroed=True, seed=6, realtime=True)
    with arm, SocketcandServer({"can0": channel}) as server:
        got = run_client(
            python,
            "damiao_motor_client.py",
            {"channel": "can0", "esc": 5, "mst": 0x15, "model": "4310", "target": 0.4},
            {"CAN_CONFIG": json.dumps({"host": server.host, "port": server.port})},
        )
        motor = arm.motors["joint_5"]
        with arm.bus.lock:
            truth_rad, state, requests = motor.joint_rad(), motor.state, dict(motor.requests)
    # registers 21-23, 10, 9, 8, 7 as the simulated DM4310 holds them (JSON turns the keys into strings)
    assert got["registers"] == {"21": 12.5, "22": 30.0, "23": 10.0, "10": 1, "9": 0, "8": 5, "7": 0x15}
    assert (got["first"]["status"], got["first"]["can_id"], got["first"]["arbitration_id"]) == ("DISABLED", 5, 0x15)
    assert got["moved"]["status"] == "ENABLED"
    assert got["moved"]["pos"] == pytest.approx(0.4, abs=0.01)
    assert truth_rad == pytest.approx(got["moved"]["pos"], abs=0.01)
    assert state == State.DISABLED  # its disable() was obeyed
    assert requests["read"] == 7 and requests["enable"] == 1 and requests["refresh"] == 1 and requests["mit"] >= 1
    assert "write" not in requests and "save" not in requests
