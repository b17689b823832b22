"""The socketcand server: python-can's own ``socketcand`` client over a real loopback TCP socket reaches a
simulated Robstride motor on an in-process ``virtual`` channel, and never gets its own frames back."""

from __future__ import annotations

import itertools
import re
import socket
import struct
from collections.abc import Iterator

import can
import pytest

from robocal.backends.robstride.protocol import CommType, Param, make_id, split_id
from robocal.backends.robstride.sim import SimMotor, SimMotorBus
from robocal.backends.sim.socketcand import SocketcandServer, format_frame, parse_send
from robocal.errors import UsageError

pytestmark = pytest.mark.timeout(60)

_counter = itertools.count()
REPLY_WAIT_S = 10.0
"""Hang guard for one reply (the simulator answers at once; only a loaded machine makes it late)."""


def _recv_extended(bus: can.BusABC, timeout_s: float = REPLY_WAIT_S) -> can.Message:
    msg = bus.recv(timeout=timeout_s)
    assert msg is not None, "no frame"
    return msg


@pytest.fixture
def served() -> Iterator[tuple[SocketcandServer, SimMotor, str]]:
    channel = f"socketcand-test-{next(_counter)}"
    motor = SimMotor(can_id=11, model="rs-02", factory_zero_rad=0.5, q_rad=0.0)
    with SimMotorBus(channel, [motor]), SocketcandServer({"can0": channel}) as server:
        yield server, motor, channel


def test_python_can_client_reads_a_parameter(served: tuple[SocketcandServer, SimMotor, str]) -> None:
    server, motor, _ = served
    assert server.host == "127.0.0.1" and server.port > 0
    assert server.client_kwargs("can0") == {"channel": "can0", "host": "127.0.0.1", "port": server.port}
    bus = can.Bus(interface="socketcand", **server.client_kwargs("can0"))
    try:
        request = make_id(CommType.PARAM_READ, 0xFD, 11)
        bus.send(can.Message(arbitration_id=request, data=struct.pack("<HHI", Param.VBUS, 0, 0)))
        reply = _recv_extended(bus)
        comm, data16, low = split_id(reply.arbitration_id)
        assert (comm, data16 & 0xFF, low) == (CommType.PARAM_READ, 11, 0xFD)
        assert reply.is_extended_id and reply.dlc == 8
        assert struct.unpack("<H", bytes(reply.data[:2]))[0] == Param.VBUS
        assert struct.unpack("<f", bytes(reply.data[4:8]))[0] == 24.0
        assert bus.recv(timeout=0.2) is None  # the request itself never comes back
        assert motor.requests == {CommType.PARAM_READ: 1}
    finally:
        bus.shutdown()


def test_two_clients_see_each_other_but_not_themselves(
    served: tuple[SocketcandServer, SimMotor, str],
) -> None:
    server, _, _ = served
    a = can.Bus(interface="socketcand", **server.client_kwargs("can0"))
    b = can.Bus(interface="socketcand", **server.client_kwargs("can0"))
    try:
        b.send(can.Message(arbitration_id=0x123, data=b"", is_extended_id=False))  # releases b's hold
        first = _recv_extended(a)
        assert (first.arbitration_id, first.is_extended_id, bytes(first.data)) == (0x123, False, b"")
        request = make_id(CommType.ENABLE, 0xAA, 11)
        a.send(can.Message(arbitration_id=request, data=bytes(8)))
        seen_by_b = [_recv_extended(b), _recv_extended(b)]
        # b sees a's enable and the motor's reply to a (mode 2 "run" in bits 23-22, motor 11, host 0xAA)
        assert [m.arbitration_id for m in seen_by_b] == [request, 0x0280_0BAA]
        reply = _recv_extended(a)
        assert reply.arbitration_id == 0x0280_0BAA
        assert a.recv(timeout=0.2) is None  # a got the motor's reply only, not its own enable
    finally:
        a.shutdown()
        b.shutdown()


def test_unknown_bus_is_refused_by_the_client(served: tuple[SocketcandServer, SimMotor, str]) -> None:
    server, _, _ = served
    with pytest.raises(can.CanError, match="could not open bus"):
        can.Bus(interface="socketcand", channel="can7", host=server.host, port=server.port)


def _raw_session(server: SocketcandServer) -> socket.socket:
    sock = socket.create_connection((server.host, server.port), timeout=REPLY_WAIT_S)
    assert sock.recv(256) == b"< hi >"
    sock.sendall(b"< open can0 >")
    assert sock.recv(256) == b"< ok >"
    sock.sendall(b"< rawmode >")
    assert sock.recv(256) == b"< ok >"
    return sock


def _read_until(sock: socket.socket, end: bytes) -> bytes:
    data = b""
    while not data.endswith(end):
        chunk = sock.recv(4096)
        assert chunk, f"closed after {data!r}"
        data += chunk
    return data


def test_raw_protocol_replies(served: tuple[SocketcandServer, SimMotor, str]) -> None:
    server, motor, _ = served
    sock = _raw_session(server)
    try:
        sock.sendall(b"< echo >")
        assert _read_until(sock, b">") == b"< echo >"
        sock.sendall(b"< send 123 9 0 0 0 0 0 0 0 0 0 >")
        assert _read_until(sock, b">") == b"< error dlc 9 with 9 data bytes >"
        sock.sendall(b"< subscribe 0 0 123 >")
        assert _read_until(sock, b">") == b"< error unknown command >"
        # a stop request with the firmware query, split over two TCP writes
        sock.sendall(b"< send 0400FD0B 8 0 c4 0")
        sock.sendall(b" 0 0 0 0 0 >")
        frame = _read_until(sock, b">").decode()
        # the reply is type 4 from motor 11 (bits 15-8) to host 0xFD, firmware 0.0.3.6
        assert re.fullmatch(r"< frame 04000BFD \d+\.\d{6} 00C4000003060000 >", frame), frame
        assert motor.requests == {CommType.STOP: 1}
    finally:
        sock.close()


def test_frame_text_matches_the_daemon() -> None:
    assert format_frame(0x123, bytes.fromhex("1a220344"), 23.424242, extended=False) == (
        "< frame 123 23.424242 1A220344 >"
    )
    assert format_frame(0x1F334455, b"", 1.000001, extended=True) == "< frame 1F334455 1.000001  >"
    assert parse_send("send 0C00FD7F 8 1e 70 0 0 0 0 0 ff") == (0x0C00FD7F, True, bytes.fromhex("1e700000000000ff"))
    assert parse_send("send 7F 0") == (0x7F, False, b"")
    for bad in ("send 123 2 1", "send 800 0", "send 123 1 100", "open can0"):
        with pytest.raises(ValueError):
            parse_send(bad)


def test_bus_names_the_protocol_cannot_carry_are_refused() -> None:
    for name in ("", "a b", "x" * 17, "<can>"):
        with pytest.raises(UsageError):
            SocketcandServer({name: "virtual-x"})
    with pytest.raises(UsageError):
        SocketcandServer({})
