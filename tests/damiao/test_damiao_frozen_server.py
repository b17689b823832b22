"""A socketcand server that accepts the connection and then says nothing (its process frozen: SIGSTOP) must not hang
a Damiao bus: python-can's client waits for the greeting without a timeout, so the bus gives up after its open
deadline with a device error (exit 3). Found by the Damiao fault soak (issue 26: a frozen ``robocal sim openarm`` at
start-up held ``sweep --auto --write-zero`` until the harness's 600 s hang guard)."""

from __future__ import annotations

import socket
import time

import pytest

pytest.importorskip("can")

import robocal.backends.damiao.bus as dbus
from robocal.backends.damiao.bus import DamiaoBus, DamiaoMotor
from robocal.errors import DeviceError

pytestmark = pytest.mark.timeout(120)


def test_a_silent_socketcand_server_is_a_device_error_not_a_hang(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(dbus, "OPEN_DEADLINE_S", 1.0)
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as server:
        server.bind(("127.0.0.1", 0))
        server.listen(4)  # the kernel completes the TCP handshake; nobody ever answers
        port = server.getsockname()[1]
        t0 = time.monotonic()
        with pytest.raises(DeviceError, match=r"cannot open CAN socketcand:can0: no answer within 1\.1 s"):
            DamiaoBus(
                "can0",
                [DamiaoMotor("gripper", 0x08, 0x18, "DM4310")],
                interface="socketcand",
                allow_motion=True,
                bus_kwargs={"host": "127.0.0.1", "port": port},
            )
        assert time.monotonic() - t0 < 60  # a hang guard: it gave up (the deadline is 1.1 s)

