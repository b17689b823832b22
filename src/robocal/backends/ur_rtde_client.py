"""UR RTDE receive client (TCP port 30004): joint positions and the controller's own TCP pose.

Wire format (big-endian, RTDE protocol version 2): each packet is ``uint16 size`` (the 3-byte header included),
``uint8 type``, payload. The client sends REQUEST_PROTOCOL_VERSION (``'V'``, ``uint16 2``; the reply's
``uint8`` is 1 when accepted), CONTROL_PACKAGE_SETUP_OUTPUTS (``'O'``: ``float64`` frequency, then the
comma-separated output names; the reply is a ``uint8`` recipe id, 0 when refused, and the comma-separated types,
``NOT_FOUND`` for an output the controller does not have), CONTROL_PACKAGE_START (``'S'``, reply ``uint8`` 1)
and then reads DATA_PACKAGEs (``'U'``: ``uint8`` recipe id, the values in recipe order). Other packets (text
messages) are skipped. The recipe is ``actual_q``, ``actual_TCP_pose`` and ``tcp_offset`` (each VECTOR6D, six
``float64``). Connecting and each read are bounded by ``timeout_s`` (host-name resolution included).
"""

from __future__ import annotations

import socket
import struct
import time

from ..core.lifecycle import ClosesOnExit
from ..errors import CalibTimeoutError, DeviceError, ProtocolError
from .ur_primary import PoseSample, check_connection_args, connect_tcp

__all__ = ["DEFAULT_RTDE_PORT", "RTDE_RECIPE", "RtdeReceiveClient"]

DEFAULT_RTDE_PORT = 30004
"""The controller's RTDE port."""
RTDE_RECIPE = ("actual_q", "actual_TCP_pose", "tcp_offset")
"""Outputs asked for, each a VECTOR6D."""
_PROTOCOL_VERSION = 2
_FREQUENCY_HZ = 125.0  # every controller serves 125 Hz (CB3's most; e-Series up to 500)
_VECTORS = struct.Struct(">" + "6d" * len(RTDE_RECIPE))


class RtdeReceiveClient(ClosesOnExit):
    """Read joint positions and the base → TCP pose over RTDE (context manager; connects on the first read).

    Args:
        host: Controller address.
        port: RTDE port.
        timeout_s: Deadline for connecting and the setup, and again for each data package.
    """

    def __init__(self, host: str, port: int = DEFAULT_RTDE_PORT, timeout_s: float = 10.0) -> None:
        self.host = host
        self.port = port
        self.timeout_s = timeout_s
        self._sock: socket.socket | None = None
        self._deadline = 0.0
        self._recipe_id = 0

    @property
    def _where(self) -> str:
        return f"UR controller {self.host}:{self.port} (RTDE)"

    def connect(self) -> None:
        """Open the connection, negotiate protocol version 2, set the recipe up and start the data.

        Raises:
            UsageError: Empty host, port outside 1..65535 or a bad timeout (exit 2).
            DeviceError: Cannot resolve or connect, or the connection closes (exit 3).
            ProtocolError: The controller refuses version 2, the recipe or the start.
            CalibTimeoutError: No answer within ``timeout_s``.
        """
        if self._sock is not None:
            return
        check_connection_args(self.host, self.port, self.timeout_s)
        self._deadline = time.monotonic() + self.timeout_s
        self._sock = connect_tcp(self.host, self.port, self.timeout_s, self._where, self._remaining)
        try:
            self._setup()
        except BaseException:
            self.close()
            raise

    def _setup(self) -> None:
        if self._request("V", struct.pack(">H", _PROTOCOL_VERSION))[:1] != b"\x01":
            raise ProtocolError(f"{self._where}: the controller refuses RTDE protocol version {_PROTOCOL_VERSION}")
        reply = self._request("O", struct.pack(">d", _FREQUENCY_HZ) + ",".join(RTDE_RECIPE).encode())
        types = reply[1:].decode("ascii", "replace").split(",")
        if not reply or reply[0] == 0 or types != ["VECTOR6D"] * len(RTDE_RECIPE):
            got = ", ".join(f"{n}: {t}" for n, t in zip(RTDE_RECIPE, types, strict=False))
            raise ProtocolError(f"{self._where}: output recipe refused ({got or 'no types'})")
        self._recipe_id = reply[0]
        if self._request("S", b"")[:1] != b"\x01":
            raise ProtocolError(f"{self._where}: the controller refuses to start the data")

    def close(self) -> None:
        """Close the connection (idempotent)."""
        if self._sock is not None:
            try:
                self._sock.close()
            finally:
                self._sock = None

    def _remaining(self, what: str) -> float:
        left = self._deadline - time.monotonic()
        if left <= 0:
            raise CalibTimeoutError(f"{self._where}: no answer within {self.timeout_s:g} s ({what})")
        return left

    def _recv_exact(self, n: int, what: str) -> bytes:
        assert self._sock is not None
        buf = bytearray()
        while len(buf) < n:
            self._sock.settimeout(self._remaining(what))
            try:
                chunk = self._sock.recv(n - len(buf))
            except TimeoutError:
                raise CalibTimeoutError(f"{self._where}: no answer within {self.timeout_s:g} s ({what})") from None
            except OSError as exc:
                raise DeviceError(f"{self._where}: connection lost ({exc.strerror or exc})") from None
            if not chunk:
                raise DeviceError(f"{self._where}: connection closed while waiting for {what}")
            buf += chunk
        return bytes(buf)

    def _read_packet(self, what: str) -> tuple[str, bytes]:
        size, kind = struct.unpack(">HB", self._recv_exact(3, what))
        if size < 3:
            raise ProtocolError(f"{self._where}: packet size {size} is below its 3-byte header")
        return chr(kind), self._recv_exact(size - 3, what)

    def _request(self, kind: str, payload: bytes) -> bytes:
        """Send one control packet and return the payload of its reply (packets of other types skipped)."""
        assert self._sock is not None
        try:
            self._sock.sendall(struct.pack(">HB", len(payload) + 3, ord(kind)) + payload)
        except OSError as exc:
            raise DeviceError(f"{self._where}: connection lost ({exc.strerror or exc})") from None
        while True:
            got, body = self._read_packet(f"the reply to {kind!r}")
            if got == kind:
                return body

    def read_sample(self) -> PoseSample:
        """The next data package (its own deadline of ``timeout_s``).

        Raises:
            DeviceError: The connection closes. ProtocolError: a package of the wrong size.
            CalibTimeoutError: No package within ``timeout_s``.
        """
        if self._sock is None:
            self.connect()
        self._deadline = time.monotonic() + self.timeout_s
        while True:
            kind, body = self._read_packet("a data package")
            if kind != "U" or not body or body[0] != self._recipe_id:
                continue
            if len(body) != 1 + _VECTORS.size:
                raise ProtocolError(
                    f"{self._where}: data package of {len(body) - 1} bytes; expected {_VECTORS.size}"
                )
            v = _VECTORS.unpack_from(body, 1)
            return PoseSample(tuple(v[0:6]), (v[6], v[7], v[8]), (v[9], v[10], v[11]), tuple(v[12:18]))

    def read_pose_samples(self, count: int) -> list[PoseSample]:
        """``count`` consecutive data packages."""
        return [self.read_sample() for _ in range(count)]
