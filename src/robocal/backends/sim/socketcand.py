"""A socketcand server on loopback TCP: CAN clients in other processes reach the in-process simulated buses.

The simulated CAN devices (:class:`~.robstride.SimMotorBus`, the Damiao bus, …) answer on python-can
``virtual`` channels, which only the simulator's own process can open. :class:`SocketcandServer` speaks the
socketcand protocol (linux-can/socketcand, ``doc/protocol.md``; the daemon's RAW mode) on ``127.0.0.1`` and
bridges each TCP client to one of those channels, so python-can's own ``socketcand`` interface, unmodified, is a
client of the simulator::

    server = SocketcandServer({"can0": "robocal-sim-lite-can0"})      # bus name → virtual channel
    with server:
        bus = can.Bus(interface="socketcand", **server.client_kwargs("can0"))
        # == can.Bus(interface="socketcand", channel="can0", host="127.0.0.1", port=server.port)

What a client sees, as from the daemon:

- On connect ``< hi >``; ``< open NAME >`` → ``< ok >`` (a name not served: ``< error could not open bus >``);
  ``< rawmode >`` → ``< ok >``; ``< echo >`` → ``< echo >``; ``< bcmmode >`` → ``< ok >``; anything else
  ``< error unknown command >``. Each handshake reply is sent alone, as python-can reads each with one ``recv``.
- In RAW mode ``< send ID DLC B0 … >`` puts the frame on the channel (extended iff the id text has 8
  characters; DLC above 8 or a byte count that differs from the DLC is refused with ``< error … >``, where the
  daemon stays silent), and every frame another party sends on the channel comes back as
  ``< frame ID SEC.USEC DATA >`` (``%03X`` / ``%08X``, data in upper-case hex, two spaces before ``>`` when
  empty).
- **A client never receives its own frames.** Each client has its own ``virtual`` bus on the channel with
  ``receive_own_messages=False``, as the daemon's CAN_RAW socket does not receive what it sent (Linux default
  ``recv_own_msgs`` off); two clients on one channel see each other's frames, as on a real bus.
- Frames that arrive in the first :attr:`SocketcandServer.hold_s` after ``< rawmode >``'s ``< ok >`` wait until
  the client has sent its first frame or that time has passed, so they never share a TCP read with the ``< ok >``
  (python-can's handshake requires the exact text).

BCM-mode jobs (``add``, ``update``, ``subscribe``, …) are not served (``< error unknown command >``); python-can
uses RAW mode only.
"""

from __future__ import annotations

import contextlib
import re
import socket
import threading
import time
from collections.abc import Mapping
from typing import Any

from ...core.lifecycle import StartsOnEnter
from ...errors import DeviceError, UsageError
from .. import require
from ._sockets import LoopbackServer

__all__ = ["SocketcandServer", "format_frame", "parse_send"]

_COMMAND = re.compile(r"<([^<>]*)>")
_MAX_COMMAND = 512
"""A command longer than this without its closing ``>`` ends the connection (the daemon's buffer is smaller)."""


def format_frame(arbitration_id: int, data: bytes, timestamp_s: float, *, extended: bool) -> str:
    """A received frame as the daemon writes it: ``< frame 0C00FD7F 12.000500 1E70 >``.

    Args:
        arbitration_id: CAN id.
        data: Payload (0-8 bytes).
        timestamp_s: Receive time, s.
        extended: 29-bit id (``%08X``) or 11-bit (``%03X``).
    """
    ident = f"{arbitration_id & 0x1FFFFFFF:08X}" if extended else f"{arbitration_id & 0x7FF:03X}"
    sec = int(timestamp_s)
    usec = min(round((timestamp_s - sec) * 1e6), 999_999)
    return f"< frame {ident} {sec}.{usec:06d} {bytes(data).hex().upper()} >"


def parse_send(body: str) -> tuple[int, bool, bytes]:
    """Parse the inside of a RAW ``< send ID DLC B0 … >`` command (without ``<``/``>``).

    Returns:
        ``(arbitration_id, extended, data)``; the id is extended iff its text has exactly 8 characters.

    Raises:
        ValueError: Not a send command, a bad number, a DLC above 8, or a byte count other than the DLC.
    """
    words = body.split()
    if len(words) < 3 or words[0] != "send":
        raise ValueError("expected send ID DLC DATA…")
    ident, dlc_text, *data_text = words[1:]
    extended = len(ident) == 8
    arbitration_id = int(ident, 16)
    dlc = int(dlc_text, 16)
    if arbitration_id < 0 or arbitration_id > (0x1FFFFFFF if extended else 0x7FF):
        raise ValueError(f"id {ident} out of range")
    if not 0 <= dlc <= 8 or len(data_text) != dlc:
        raise ValueError(f"dlc {dlc_text} with {len(data_text)} data bytes")
    data = bytes(int(b, 16) for b in data_text)  # a byte above ff raises ValueError
    return arbitration_id, extended, data


class SocketcandServer(LoopbackServer, StartsOnEnter):
    """The socketcand protocol on loopback TCP, bridging each client to an in-process ``virtual`` CAN channel.

    Args:
        buses: Bus name a client opens (``"can0"``) → the python-can ``virtual`` channel it reaches.
        host: Address to listen on (loopback by default).
        port: Port (0: any free port; see :attr:`port`).
        hold_s: How long frames for a client that has just entered RAW mode wait for its first frame.

    Raises:
        UsageError: No bus, or a bus name the protocol cannot carry (empty, over 16 characters, spaces, ``<>``).
        DeviceError: The address cannot be listened on.

    Use as a context manager, or call :meth:`start` and :meth:`stop`.
    """

    def __init__(
        self,
        buses: Mapping[str, str],
        *,
        host: str = "127.0.0.1",
        port: int = 0,
        hold_s: float = 0.2,
    ) -> None:
        if not buses:
            raise UsageError("the socketcand server needs at least one bus")
        for name in buses:
            if not name or len(name) > 16 or re.search(r"[\s<>]", name):
                raise UsageError(f"socketcand bus name {name!r}: expected 1-16 characters, no spaces or <>")
        self.buses = dict(buses)
        self.hold_s = hold_s
        self._can: Any = require("can", "the socketcand server")
        try:
            super().__init__(host=host, port=port, name="sim-socketcand")
        except OSError as exc:
            raise DeviceError(f"cannot listen on {host}:{port} for socketcand: {exc.strerror or exc}") from None

    @property
    def host(self) -> str:
        """The address the server listens on."""
        return self.address[0]

    @property
    def port(self) -> int:
        """The TCP port the server listens on."""
        return self.address[1]

    def client_kwargs(self, bus: str) -> dict[str, Any]:
        """Keyword arguments of ``can.Bus(interface="socketcand", **…)`` that reach ``bus``."""
        if bus not in self.buses:
            raise UsageError(f"socketcand: no bus {bus!r} (served: {', '.join(self.buses)})")
        return {"channel": bus, "host": self.host, "port": self.port}

    def _serve(self, conn: socket.socket) -> None:
        _Client(self, conn).run()


class _Client:
    """One TCP connection: the command reader (this thread) and, once a bus is open, a forwarder thread."""

    def __init__(self, server: SocketcandServer, conn: socket.socket) -> None:
        self.server = server
        self.conn = conn
        self.send_lock = threading.Lock()
        self.bus: Any = None
        self.raw = False
        self.released = threading.Event()
        self.done = threading.Event()
        self.forwarder: threading.Thread | None = None

    def write(self, text: str) -> None:
        with self.send_lock:
            self.conn.sendall(text.encode("ascii"))

    def run(self) -> None:
        conn = self.conn
        conn.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
        try:
            self.write("< hi >")
            buffer = ""
            while not self.server.stopping:
                chunk = conn.recv(4096)
                if not chunk:
                    return
                buffer += chunk.decode("ascii", errors="replace")
                while True:
                    match = _COMMAND.search(buffer)
                    if match is None:
                        break
                    buffer = buffer[match.end() :]
                    self.command(match.group(1).strip())
                if len(buffer) > _MAX_COMMAND:
                    return
        finally:
            self.done.set()
            if self.forwarder is not None:
                self.forwarder.join(2.0)
            if self.bus is not None:
                with contextlib.suppress(Exception):
                    self.bus.shutdown()

    def command(self, body: str) -> None:
        word = body.split(" ", 1)[0]
        if word == "echo":
            self.write("< echo >")
        elif self.bus is None:
            if word == "open" and len(body.split()) == 2:
                self.open(body.split()[1])
            else:
                self.write("< error unknown command >")
        elif word == "rawmode":
            self.raw = True
            self.write("< ok >")
            self.start_forwarding()
        elif word == "bcmmode":
            self.raw = False
            self.write("< ok >")
        elif word == "send":
            self.send(body)
        else:
            self.write("< error unknown command >")

    def open(self, name: str) -> None:
        channel = self.server.buses.get(name)
        if channel is None:
            self.write("< error could not open bus >")
            return
        self.bus = self.server._can.Bus(channel=channel, interface="virtual", receive_own_messages=False)
        self.write("< ok >")

    def send(self, body: str) -> None:
        try:
            arbitration_id, extended, data = parse_send(body)
        except ValueError as exc:
            self.write(f"< error {exc} >")
            return
        msg = self.server._can.Message(arbitration_id=arbitration_id, data=data, is_extended_id=extended)
        self.bus.send(msg)
        self.released.set()

    def start_forwarding(self) -> None:
        if self.forwarder is None:
            self.forwarder = threading.Thread(target=self.forward, name="sim-socketcand-rx", daemon=True)
            self.forwarder.start()

    def forward(self) -> None:
        """Write every frame the channel delivers to this client (not its own) while in RAW mode."""
        self.released.wait(self.server.hold_s)
        while not self.done.is_set():
            msg = self.bus.recv(timeout=0.05)
            if msg is None or not self.raw or msg.is_error_frame or msg.is_remote_frame:
                continue
            stamp = msg.timestamp or time.time()
            text = format_frame(msg.arbitration_id, bytes(msg.data), stamp, extended=msg.is_extended_id)
            try:
                self.write(text)
            except OSError:
                return
