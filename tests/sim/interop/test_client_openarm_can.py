"""PyPI's ``openarm-can`` (1.4.1, enactic's nanobind bindings of its C++ openarm_can), unchanged, in its own
environment, reads robocal's simulated OpenArm (issue 31 item 6).

openarm_can talks to a Linux SocketCAN interface only (its ``CANSocket`` opens a raw ``AF_CAN`` socket on a named
interface); it has no python-can, socketcand or TCP path. So the simulated arm is put on a SocketCAN interface
(``$ROBOCAL_VCAN``, default ``vcan0``: ``ip link add dev vcan0 type vcan && ip link set vcan0 up``) through
python-can's ``socketcan`` interface, and openarm_can is pointed at the same interface.

Skipped, saying why, where that cannot be: a kernel without SocketCAN (``AF_CAN`` not supported; the ``vcan``
module absent), no such interface, or an ``openarm-can`` that does not install (PyPI has only its sdist, whose
build clones the C++ library from GitHub with CMake's FetchContent: nothing but a package registry is reached
on robocal's development machines, so there it fails). Not run on robocal's machines for those reasons: the
client script follows openarm_can's own examples and bindings (``src/openarm_can.cpp`` of the sdist)."""

from __future__ import annotations

import math
import os
from pathlib import Path

import pytest

from robocal.backends.damiao.openarm import SimOpenArm

from .conftest import client_env_python, run_client

pytestmark = [pytest.mark.interop, pytest.mark.timeout(600)]

VCAN = os.environ.get("ROBOCAL_VCAN", "vcan0")


def socketcan_missing(interface: str) -> str | None:
    """Why ``interface`` cannot carry SocketCAN frames here (None: it can)."""
    from .client_envs import _no_socketcan

    why = _no_socketcan()
    if why is not None:
        return f"openarm_can: {why}, so it cannot reach a simulator"
    if not Path(f"/sys/class/net/{interface}").exists():
        return f"no SocketCAN interface {interface} (ip link add dev {interface} type vcan; ip link set {interface} up)"
    return None


def test_an_interface_that_is_not_there_is_named_as_the_reason() -> None:
    why = socketcan_missing("robocal-none0")  # no kernel SocketCAN, or no such interface: either is said
    assert why is not None and ("AF_CAN" in why or "no SocketCAN interface robocal-none0" in why)


def test_openarm_can_reads_the_simulated_arm_on_socketcan() -> None:
    why = socketcan_missing(VCAN)
    if why is not None:
        pytest.skip(why)
    python = client_env_python("openarm_can")
    arm = SimOpenArm(VCAN, zeroed=True, seed=8, interface="socketcan", realtime=True)
    with arm:
        arm.set_joint("joint_4", math.radians(30.0))
        got = run_client(python, "openarm_can_client.py", {"interface": VCAN})
        truth = arm.joint_angles_rad()
        requests = {n: dict(m.requests) for n, m in arm.motors.items()}
    order = [f"joint_{i}" for i in range(1, 8)] + ["gripper"]
    assert got["pmax"] == [12.5] * 8  # the simulated DM8009 / DM4340 / DM4310 registers 21
    for name, position in zip(order, got["positions"], strict=True):  # zeroed: a motor reads its joint's angle
        assert position == pytest.approx(truth[name], abs=math.radians(0.05)), name
    assert got["enabled"] == [False] * 8
    assert all("write" not in r and "save" not in r and "enable" not in r for r in requests.values())
