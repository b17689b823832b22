"""The PyPI ``robstride`` client (0.1.0, sirwart), unchanged, in its own environment, drives a simulated motor
through the socketcand server over a real loopback TCP socket (issue 29)."""

from __future__ import annotations

import itertools
import json
import math
import os
import subprocess
from pathlib import Path

import pytest

from robocal.backends.robstride import MotorSpec, RobstrideBus
from robocal.backends.robstride.protocol import CommType
from robocal.backends.robstride.sim import SimMotor, SimMotorBus
from robocal.backends.sim.socketcand import SocketcandServer

from .conftest import client_env_python, run_client

pytestmark = [pytest.mark.interop, pytest.mark.timeout(300)]

_n = itertools.count()



def _cli(python: Path, server: SocketcandServer, *args: str) -> subprocess.CompletedProcess[str]:
    """The package's own command line; python-can's CAN_CONFIG environment variable gives it host and port."""
    return subprocess.run(
        [str(python.parent / "robstride"), "--interface", "socketcand", "--channel", "can0", *args],
        capture_output=True,
        text=True,
        timeout=120,
        env=dict(
            os.environ,
            CAN_CONFIG=json.dumps({"host": server.host, "port": server.port}),
            PYTHONNOUSERSITE="1",
        ),
    )


def test_pypi_robstride_client_over_socketcand() -> None:
    python = client_env_python("robstride")
    channel = f"pypi-robstride-{next(_n)}"
    motor = SimMotor(can_id=11, model="rs-02", factory_zero_rad=0.75)
    with SimMotorBus(channel, [motor]), SocketcandServer({"can0": channel}) as server:
        got = run_client(python, "robstride_client.py", {**server.client_kwargs("can0"), "motor": 11})
        assert got["enabled"]["servo_id"] == 11
        # the client decodes the mode from bit 22 alone; run mode (2) is bit 23, so it says Reset for a running
        # motor (it would on hardware too); the simulator's state shows the enable
        assert got["enabled"]["mode"] == "Reset" and got["write_mode"] == "Reset"
        assert motor.mode == 2
        assert got["enabled"]["angle"] == pytest.approx(0.75, abs=4 * math.pi / 32768)  # 16-bit over ±4π
        assert got["vbus"] == 24.0
        assert got["run_mode"] == "Operation"
        assert got["limit_torque"] == 3.5
        assert got["mechpos"] == pytest.approx(0.75, abs=1e-6)
        assert got["stray"] == "None"  # the client never got its own requests back
        assert motor.limit_torque_nm == 3.5 and motor.host_id == 0xAA
        assert motor.requests == {CommType.ENABLE: 1, CommType.PARAM_READ: 4, CommType.PARAM_WRITE: 1}
        # robocal (host 0xFD) after the client (0xAA) talked to the motor: its MIT poll is answered to 0xAA
        with RobstrideBus(
            "can0",
            [MotorSpec("j", 11, "rs-02")],
            interface="socketcand",
            timeout_s=5.0,
            bus_options={"host": server.host, "port": server.port},
        ) as bus:
            fb = bus.zero_torque()["j"]
        assert (fb.motor_id, fb.host_id, fb.mode) == (11, 0xAA, 2)
        assert fb.position_rad == pytest.approx(0.75, abs=1e-3)
        # the package's command line stops it
        r = _cli(python, server, "disable", "11")
        assert r.returncode == 0, r.stderr[-3000:]
        assert motor.mode == 0 and motor.requests[CommType.STOP] == 1


def test_pypi_robstride_cli_reads_a_parameter_and_changes_the_id() -> None:
    python = client_env_python("robstride")
    channel = f"pypi-robstride-{next(_n)}"
    motor = SimMotor(can_id=12, model="rs-00")
    with SimMotorBus(channel, [motor]) as sim, SocketcandServer({"can0": channel}) as server:
        r = _cli(python, server, "read", "12", "vbus")
        assert r.returncode == 0, r.stderr[-3000:]
        assert r.stdout.strip() == "value: 24.0"
        # type 7: the new id in bits 23..16; the motor answers with a type-0 frame from its new id
        r = _cli(python, server, "update_id", "12", "20")
        assert r.returncode == 0, r.stderr[-3000:]
        assert motor.can_id == 20 and list(sim.motors) == [20]
        r = _cli(python, server, "read", "20", "vbus")
        assert (r.returncode, r.stdout.strip()) == (0, "value: 24.0")
