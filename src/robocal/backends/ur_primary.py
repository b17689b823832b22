"""UR primary-interface client (TCP port 30001): reads the controller's calibrated DH (KinematicsInfo).

Wire format (all big-endian):

* message: ``int32 size`` (whole message, **including** these 4 bytes), ``uint8 type``, payload;
* type 16 (ROBOT_STATE): sub-packages until the end, each ``uint32 size`` (incl. header),
  ``uint8 type``, body;
* sub-type 5 (KinematicsInfo, 225 bytes): ``6×uint32 checksum``, ``6×float64 dh_theta``, ``6×float64 dh_a``,
  ``6×float64 dh_d``, ``6×float64 dh_alpha``, ``uint32 calibration_status`` (2 = linearised).

Every other message type (20 version/robot messages, 5 MODBUS_INFO, 22, 23, 24, 25, …) and sub-package
is skipped by its length. Lengths are bounded (:data:`MAX_MESSAGE_BYTES`), so a bogus size field cannot
allocate gigabytes. Connecting and the KinematicsInfo are bounded by one deadline (default 10 s, host-name
resolution included); each pose sample of :meth:`PrimaryClient.read_pose_samples` gets the same time again.
"""

from __future__ import annotations

import math
import socket
import struct
import threading
import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from typing import Any, TypeVar

from ..core.dh import DHParameters
from ..core.lifecycle import ClosesOnExit
from ..errors import CalibTimeoutError, DeviceError, ProtocolError, UsageError

__all__ = [
    "CALIBRATION_LINEARISED",
    "DEFAULT_PORT",
    "DEFAULT_TIMEOUT_S",
    "KINEMATICS_INFO_SIZE",
    "MAX_MESSAGE_BYTES",
    "MSG_ROBOT_STATE",
    "SUB_KINEMATICS_INFO",
    "KinematicsInfo",
    "PoseSample",
    "PrimaryClient",
    "check_connection_args",
    "connect_tcp",
    "encode_cartesian_info",
    "encode_joint_data",
    "encode_kinematics_info",
    "encode_message",
    "encode_subpackage",
    "iter_subpackages",
    "parse_kinematics_info",
    "parse_pose_sample",
    "resolve_host",
]

DEFAULT_PORT = 30001
"""Primary interface port (30011 is the read-only variant)."""
DEFAULT_TIMEOUT_S = 10.0
"""Overall time allowed to connect and receive a KinematicsInfo."""
MAX_MESSAGE_BYTES = 65536
"""Largest message accepted (a real RobotState is ~1.4 kB)."""
MSG_ROBOT_STATE = 16
SUB_KINEMATICS_INFO = 5
KINEMATICS_INFO_SIZE = 225
CALIBRATION_LINEARISED = 2

_T = TypeVar("_T")
_AddrInfo = tuple[socket.AddressFamily, socket.SocketKind, int, str, Any]
_HEADER = struct.Struct(">iB")
_SUB_HEADER = struct.Struct(">IB")
_KIN_BODY = struct.Struct(">6I6d6d6d6dI")
_JOINT = struct.Struct(">dddffffB")  # q_actual, q_target, qd_actual, I, V, T_motor, T_micro, mode (41 bytes)
_CARTESIAN = struct.Struct(">6d6d")  # x, y, z, rx, ry, rz (base → TCP), then the TCP offset (96 bytes)
SUB_JOINT_DATA = 1
SUB_CARTESIAN_INFO = 4


def check_connection_args(host: str, port: int, timeout_s: float) -> None:
    """Refuse an empty host, a port outside 1..65535 or a timeout that is not a positive finite number.

    Raises:
        UsageError: Names the flag (``--host``, ``--port``, ``--timeout``); exit code 2.
    """
    if not host.strip():
        raise UsageError("--host: expected a controller address, got an empty string")
    if isinstance(port, bool) or not isinstance(port, int) or not 1 <= port <= 65535:
        raise UsageError(f"--port {port}: expected 1..65535")
    if not (timeout_s > 0 and math.isfinite(timeout_s)):
        raise UsageError(f"--timeout {timeout_s}: expected a positive number of seconds")


def resolve_host(host: str, port: int, timeout_s: float) -> list[_AddrInfo]:
    """Resolve ``host`` for a TCP connection, waiting at most ``timeout_s`` seconds.

    A numeric address is returned at once. A host name is looked up in a daemon thread, because
    ``getaddrinfo`` has no timeout of its own (a dead DNS server can block it for much longer than
    ``--timeout``); the thread is left to finish on its own when the deadline passes.

    Raises:
        DeviceError: The name cannot be resolved (exit code 3).
        CalibTimeoutError: No answer within ``timeout_s`` (exit code 3).
    """
    try:
        numeric: list[_AddrInfo] = list(
            socket.getaddrinfo(host, port, type=socket.SOCK_STREAM, flags=socket.AI_NUMERICHOST)
        )
        return numeric
    except (socket.gaierror, UnicodeError):
        pass
    where = f"UR controller {host}:{port}"
    found: list[_AddrInfo] = []
    failed: list[BaseException] = []
    done = threading.Event()

    def lookup() -> None:
        try:
            found.extend(socket.getaddrinfo(host, port, type=socket.SOCK_STREAM))
        except BaseException as exc:  # handed to the caller
            failed.append(exc)
        finally:
            done.set()

    threading.Thread(target=lookup, name=f"robocal-resolve-{host}", daemon=True).start()
    if not done.wait(timeout_s):
        raise CalibTimeoutError(f"{where}: cannot resolve host name {host!r} within {timeout_s:g} s")
    if failed:
        exc = failed[0]
        reason = exc.strerror if isinstance(exc, OSError) and exc.strerror else str(exc)
        raise DeviceError(f"{where}: cannot resolve host name {host!r} ({reason})")
    if not found:
        raise DeviceError(f"{where}: cannot resolve host name {host!r} (no address)")
    return found



def connect_tcp(host: str, port: int, timeout_s: float, where: str, remaining: Callable[[str], float]) -> socket.socket:
    """A TCP connection to the first of ``host``'s addresses that answers (``where`` names it in the messages).

    ``remaining(what)`` gives the seconds left of the caller's deadline of ``timeout_s`` (or raises the timeout).

    Raises:
        DeviceError: No address accepts the connection (exit code 3).
        CalibTimeoutError: Connecting timed out (exit code 3).
    """
    last: OSError | None = None
    for family, sock_type, proto, _, address in resolve_host(host, port, timeout_s):
        sock = socket.socket(family, sock_type, proto)
        try:
            sock.settimeout(remaining("connecting"))
            sock.connect(address)
        except TimeoutError:
            sock.close()
            raise CalibTimeoutError(f"{where}: connection timed out after {timeout_s:g} s") from None
        except OSError as exc:
            sock.close()
            last = exc
            continue
        except BaseException:
            sock.close()
            raise
        return sock
    reason = (last.strerror or str(last)) if last is not None else "no address"
    raise DeviceError(f"{where}: cannot connect ({reason})")

@dataclass(frozen=True)
class PoseSample:
    """One controller sample: joint positions and the controller's own base → TCP pose.

    Attributes:
        q_rad: Actual joint positions, radians.
        tcp_xyz_m: TCP position in the base frame, metres.
        tcp_rotvec_rad: TCP orientation as a rotation vector (Rx, Ry, Rz), radians.
        tcp_offset: The active TCP offset (x, y, z, rx, ry, rz); all zero means TCP = flange.
    """

    q_rad: tuple[float, ...]
    tcp_xyz_m: tuple[float, float, float]
    tcp_rotvec_rad: tuple[float, float, float]
    tcp_offset: tuple[float, ...]


def encode_joint_data(q_rad: tuple[float, ...] | list[float]) -> bytes:
    """Encode a Joint sub-package (type 1, 251 bytes) with ``q_actual = q_target = q_rad``."""
    body = b"".join(_JOINT.pack(float(q), float(q), 0.0, 0.0, 48.0, 30.0, 0.0, 253) for q in q_rad)
    return encode_subpackage(SUB_JOINT_DATA, body)


def encode_cartesian_info(xyz_m: tuple[float, ...], rotvec_rad: tuple[float, ...]) -> bytes:
    """Encode a CartesianInfo sub-package (type 4, 101 bytes) with a zero TCP offset."""
    return encode_subpackage(SUB_CARTESIAN_INFO, _CARTESIAN.pack(*xyz_m, *rotvec_rad, *([0.0] * 6)))


def parse_pose_sample(payload: bytes) -> PoseSample | None:
    """Joint positions + CartesianInfo from one RobotState payload (None when either is absent).

    Raises:
        ProtocolError: A Joint or CartesianInfo sub-package is truncated or holds a non-finite value.
    """
    q: tuple[float, ...] | None = None
    cart: tuple[float, ...] | None = None
    for sub_type, sub in iter_subpackages(payload):
        if sub_type == SUB_JOINT_DATA:
            if len(sub) < 5 + 6 * _JOINT.size:
                raise ProtocolError(f"Joint data: {len(sub)} bytes, expected {5 + 6 * _JOINT.size}")
            q = tuple(_JOINT.unpack_from(sub, 5 + i * _JOINT.size)[0] for i in range(6))
        elif sub_type == SUB_CARTESIAN_INFO:
            if len(sub) < 5 + _CARTESIAN.size:
                raise ProtocolError(f"CartesianInfo: {len(sub)} bytes, expected {5 + _CARTESIAN.size}")
            cart = _CARTESIAN.unpack_from(sub, 5)
    if q is None or cart is None:
        return None
    if not all(math.isfinite(v) for v in (*q, *cart)):
        raise ProtocolError("Joint data / CartesianInfo: non-finite value")
    return PoseSample(q, (cart[0], cart[1], cart[2]), (cart[3], cart[4], cart[5]), tuple(cart[6:12]))


@dataclass(frozen=True)
class KinematicsInfo:
    """Decoded KinematicsInfo sub-package.

    Attributes:
        checksum: Per-joint checksums (URSim sends 0xFFFFFFFF).
        dh: Calibrated DH (nominal + controller deltas), radians and metres.
        calibration_status: 0 not initialised, 1 not linearised, 2 linearised (real robots report 2).
    """

    checksum: tuple[int, ...]
    dh: DHParameters
    calibration_status: int

    @property
    def linearised(self) -> bool:
        """True when ``calibration_status`` is 2."""
        return self.calibration_status == CALIBRATION_LINEARISED


def encode_message(msg_type: int, payload: bytes) -> bytes:
    """Frame a primary-interface message: ``int32 size`` (incl. header) + ``uint8 type`` + payload."""
    return _HEADER.pack(len(payload) + _HEADER.size, msg_type) + payload


def encode_subpackage(sub_type: int, body: bytes) -> bytes:
    """Frame a RobotState sub-package: ``uint32 size`` (incl. header) + ``uint8 type`` + body."""
    return _SUB_HEADER.pack(len(body) + _SUB_HEADER.size, sub_type) + body


def encode_kinematics_info(
    dh: DHParameters, calibration_status: int = 2, checksum: int = 0xFFFFFFFF
) -> bytes:
    """Encode a KinematicsInfo sub-package (225 bytes, header included) from a six-joint DH model."""
    body = _KIN_BODY.pack(
        *([checksum] * 6), *dh.theta_rad, *dh.a_m, *dh.d_m, *dh.alpha_rad, calibration_status
    )
    return encode_subpackage(SUB_KINEMATICS_INFO, body)


def iter_subpackages(payload: bytes) -> Iterator[tuple[int, bytes]]:
    """Walk the sub-packages of a RobotState payload (after the message header).

    Yields:
        ``(sub_type, sub_package_bytes_including_header)``.

    Raises:
        ProtocolError: A sub-package length is shorter than its header or runs past the message.
    """
    off = 0
    n = len(payload)
    while off < n:
        if n - off < _SUB_HEADER.size:
            raise ProtocolError(
                f"RobotState: {n - off} trailing byte(s) at offset {off}, too short for a header"
            )
        size, sub_type = _SUB_HEADER.unpack_from(payload, off)
        if size < _SUB_HEADER.size or size > n - off:
            raise ProtocolError(
                f"RobotState: sub-package type {sub_type} at offset {off} claims {size} bytes; "
                f"{n - off} remain in the message"
            )
        yield sub_type, payload[off : off + size]
        off += size


def parse_kinematics_info(sub: bytes) -> tuple[KinematicsInfo, bool]:
    """Decode a KinematicsInfo sub-package (header included).

    Returns:
        ``(info, longer)`` where ``longer`` is True when the sub-package had extra bytes (ignored).

    Raises:
        ProtocolError: Truncated (shorter than 225 bytes) or a non-finite DH value.
    """
    if len(sub) < KINEMATICS_INFO_SIZE:
        raise ProtocolError(
            f"KinematicsInfo: {len(sub)} bytes, expected {KINEMATICS_INFO_SIZE} (truncated sub-package)"
        )
    vals = _KIN_BODY.unpack_from(sub, _SUB_HEADER.size)
    checksum = tuple(int(v) for v in vals[0:6])
    arrays = [tuple(float(v) for v in vals[6 + 6 * k : 12 + 6 * k]) for k in range(4)]
    for name, arr in zip(("dh_theta", "dh_a", "dh_d", "dh_alpha"), arrays, strict=True):
        for i, v in enumerate(arr):
            if not math.isfinite(v):
                raise ProtocolError(f"KinematicsInfo: {name}[{i}] is {v}; expected a finite number")
    dh = DHParameters(theta_rad=arrays[0], a_m=arrays[1], d_m=arrays[2], alpha_rad=arrays[3])
    info = KinematicsInfo(checksum=checksum, dh=dh, calibration_status=int(vals[30]))
    return info, len(sub) > KINEMATICS_INFO_SIZE


@dataclass
class PrimaryClient(ClosesOnExit):
    """Blocking client for the UR primary interface; registered as backend ``"ur_primary"``.

    Example:
        >>> with PrimaryClient("192.168.1.10") as client:  # doctest: +SKIP
        ...     info = client.read_kinematics()

    Attributes:
        host: Controller address.
        port: TCP port (30001; 30011 read-only).
        timeout_s: Overall deadline for connecting and receiving a KinematicsInfo, seconds.
        warnings: Human-readable warnings collected while reading (status ≠ 2, over-long sub-package).
    """

    host: str
    port: int = DEFAULT_PORT
    timeout_s: float = DEFAULT_TIMEOUT_S
    warnings: list[str] = field(default_factory=list)
    _sock: socket.socket | None = field(default=None, repr=False)
    _deadline: float = field(default=0.0, repr=False)
    _awaiting: str = field(default="KinematicsInfo", repr=False)  # what a timeout message says was missing
    _detail: str = field(default="", repr=False)  # and which sample / what the messages that came lacked

    @property
    def _where(self) -> str:
        return f"UR controller {self.host}:{self.port}"

    def _timeout(self, what: str) -> CalibTimeoutError:
        detail = f"{self._detail}; {what}" if self._detail else what
        return CalibTimeoutError(f"{self._where}: no {self._awaiting} within {self.timeout_s:g} s ({detail})")

    def _remaining(self, what: str) -> float:
        left = self._deadline - time.monotonic()
        if left <= 0:
            raise self._timeout(what)
        return left

    def connect(self) -> None:
        """Open the TCP connection (bounded by the timeout)."""
        if self._sock is not None:
            return
        check_connection_args(self.host, self.port, self.timeout_s)  # getaddrinfo would wrap port 70000
        self._deadline = time.monotonic() + self.timeout_s
        self._sock = connect_tcp(self.host, self.port, self.timeout_s, self._where, self._remaining)

    def close(self) -> None:
        """Close the connection (idempotent)."""
        if self._sock is not None:
            try:
                self._sock.close()
            finally:
                self._sock = None

    def _recv_exact(self, n: int, what: str) -> bytes:
        assert self._sock is not None
        buf = bytearray()
        while len(buf) < n:
            self._sock.settimeout(self._remaining(f"waiting for {what}"))
            try:
                chunk = self._sock.recv(min(n - len(buf), 65536))
            except TimeoutError:
                raise self._timeout(f"waiting for {what}") from None
            except OSError as exc:
                raise DeviceError(f"{self._where}: connection lost ({exc.strerror or exc})") from None
            if not chunk:
                if buf or what != "a message header":
                    raise ProtocolError(
                        f"{self._where}: connection closed in the middle of {what} "
                        f"({len(buf)} of {n} bytes; truncated message)"
                    )
                raise DeviceError(f"{self._where}: connection closed before a KinematicsInfo arrived")
            buf += chunk
        return bytes(buf)

    def read_message(self) -> tuple[int, bytes]:
        """Read one message.

        Returns:
            ``(type, payload)`` with the 5-byte header removed.

        Raises:
            ProtocolError: Size field out of bounds, or the stream ended mid-message.
            CalibTimeoutError: The deadline passed.
        """
        self.connect()
        header = self._recv_exact(_HEADER.size, "a message header")
        size, msg_type = _HEADER.unpack(header)
        if size < _HEADER.size or size > MAX_MESSAGE_BYTES:
            raise ProtocolError(
                f"{self._where}: message type {msg_type} has size {size}; expected {_HEADER.size}.."
                f"{MAX_MESSAGE_BYTES} bytes (garbage or not a primary interface)"
            )
        payload = self._recv_exact(size - _HEADER.size, f"a {size}-byte message of type {msg_type}")
        return msg_type, payload

    def read_kinematics(self) -> KinematicsInfo:
        """Read messages until the first RobotState that carries a KinematicsInfo and decode it.

        Returns:
            The controller's calibrated DH and calibration status. A status other than 2 adds a warning
            to :attr:`warnings` (the DH may not be the robot's real calibration).

        Raises:
            CalibTimeoutError: Nothing usable within ``timeout_s`` (a silent server, pre-3.6 software).
            ProtocolError: Truncated, garbage or oversized packets.
            DeviceError: Connection refused or closed.
        """
        if self._sock is not None:  # already connected (e.g. after samples): a fresh deadline for this read
            self._deadline = time.monotonic() + self.timeout_s
        self._awaiting, self._detail = "KinematicsInfo", ""
        info, size = next(self._robot_states(self._find_kinematics))
        if size > KINEMATICS_INFO_SIZE:
            self.warnings.append(
                f"{self._where}: KinematicsInfo is {size} bytes (expected "
                f"{KINEMATICS_INFO_SIZE}); extra bytes ignored"
            )
        if not info.linearised:
            self.warnings.append(
                f"{self._where}: calibration_status is {info.calibration_status}, not 2 "
                "(linearised); the DH may be nominal rather than the robot's calibration"
            )
        return info

    def read_pose_samples(self, count: int) -> list[PoseSample]:
        """Collect ``count`` (joint positions, base → TCP pose) samples from consecutive RobotStates.

        The controller streams at ~10 Hz, so ``count`` samples take about ``count / 10`` s. ``timeout_s``
        applies to each sample (each read), not to all of them together.

        Raises:
            CalibTimeoutError: One sample did not arrive within ``timeout_s``; the message says which sample
                and, when RobotStates did arrive, which sub-package (Joint data, CartesianInfo) they lacked.
        """
        self.connect()
        samples: list[PoseSample] = []
        self._awaiting = "RobotState with Joint data and CartesianInfo"
        for k in range(1, count + 1):
            self._detail = f"sample {k} of {count}"
            self._deadline = time.monotonic() + self.timeout_s
            samples.append(next(self._robot_states(self._decode_pose)))
        return samples

    def _robot_states(self, decode: Callable[[bytes], _T | None]) -> Iterator[_T]:
        """Decode every RobotState payload with ``decode`` (other messages skipped); yield the non-None results.

        Protocol errors raised by ``decode`` are re-raised naming the controller.
        """
        self.connect()
        while True:
            msg_type, payload = self.read_message()
            if msg_type != MSG_ROBOT_STATE:
                continue
            try:
                found = decode(payload)
            except ProtocolError as exc:
                raise ProtocolError(f"{self._where}: {exc}") from None
            if found is not None:
                yield found

    def _decode_pose(self, payload: bytes) -> PoseSample | None:
        """A pose sample, or None; then the timeout detail names the sub-packages the RobotState lacked."""
        sample = parse_pose_sample(payload)
        if sample is None:
            present = {sub_type for sub_type, _ in iter_subpackages(payload)}
            lacking = [
                name
                for sub_type, name in ((SUB_JOINT_DATA, "Joint data"), (SUB_CARTESIAN_INFO, "CartesianInfo"))
                if sub_type not in present
            ]
            sample_k = self._detail.split(";")[0]
            self._detail = f"{sample_k}; the RobotStates that arrived lack {' and '.join(lacking)}"
        return sample

    @staticmethod
    def _find_kinematics(payload: bytes) -> tuple[KinematicsInfo, int] | None:
        for sub_type, sub in iter_subpackages(payload):
            if sub_type == SUB_KINEMATICS_INFO:
                info, _ = parse_kinematics_info(sub)
                return info, len(sub)
        return None
