"""A socketcand server that accepts the connection and then says nothing (its process frozen: SIGSTOP) must not hang
robocal: python-can's client waits for the greeting without a timeout, so the bus gives up after its open deadline
with a device error (exit 3). Found by the fault harness (a frozen ``robocal sim lite`` at start-up hung
``sweep --auto`` for minutes)."""

from __future__ import annotations

import socket
import time

import pytest

import robocal.backends.robstride.bus as rbus
from robocal.backends.robstride import MotorSpec, RobstrideBus
from robocal.errors import DeviceError

pytestmark = pytest.mark.timeout(120)


def test_a_silent_socketcand_server_is_a_device_error_not_a_hang(monkeypatch: pytest.MonkeyPatch) -> None:
    pytest.importorskip("can")
    monkeypatch.setattr(rbus, "OPEN_DEADLINE_S", 1.0)
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as server:
        server.bind(("127.0.0.1", 0))
        server.listen(4)  # the kernel completes the TCP handshake; nobody ever answers
        port = server.getsockname()[1]
        t0 = time.monotonic()
        with pytest.raises(DeviceError, match=r"no answer within 1\.1 s"):
            RobstrideBus(
                "can0",
                [MotorSpec("j", 11, "rs-05")],
                interface="socketcand",
                bus_options={"host": "127.0.0.1", "port": port},
            )
        assert time.monotonic() - t0 < 60  # a hang guard: it gave up (the deadline is 1.1 s)
