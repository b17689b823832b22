"""Simulated UR controller: a loopback TCP server speaking the primary interface.

On connect it sends a version message (type 20), then at 10 Hz a MODBUS_INFO message (top-level
type 5, which a client must not confuse with sub-type 5) and a RobotState (type 16) with the sub-package
sequence of a URSim 5.8 UR5e (RobotMode, Joint, CartesianInfo, KinematicsInfo, CalibrationData,
Masterboard, Tool, Configuration, ForceMode, AdditionalInfo, Safety, ToolComm, ToolMode; 1386 bytes,
KinematicsInfo at offset 404) with the KinematicsInfo built from a given DH set. Fault modes send
truncated, garbage or oversized packets, or nothing, or RobotStates without CartesianInfo.
"""

from __future__ import annotations

import contextlib
import math
import socket
import struct
import threading
import time

from ...core.dh import DHParameters, fk_dh
from ...core.lifecycle import StartsOnEnter
from ...core.se3 import rotvec_from_matrix
from ..ur_primary import (
    encode_cartesian_info,
    encode_joint_data,
    encode_kinematics_info,
    encode_message,
    encode_subpackage,
)
from ._sockets import accept_loop
from .ur_arm_state import RobotModeSample, UrArmState, encode_robot_mode_data

__all__ = [
    "FAULT_MODES",
    "ROBOT_STATE_LAYOUT",
    "SimUrController",
    "build_robot_state",
    "build_version_message",
]

ROBOT_STATE_LAYOUT: tuple[tuple[int, int], ...] = (
    (0, 47),
    (1, 251),
    (4, 101),
    (5, 225),
    (9, 53),
    (3, 75),
    (2, 37),
    (6, 445),
    (7, 61),
    (8, 9),
    (10, 43),
    (11, 26),
    (12, 8),
)
"""(sub-type, size incl. header) of a URSim 5.8 UR5e RobotState."""

FAULT_MODES: tuple[str, ...] = (
    "normal",
    "truncated",
    "garbage",
    "oversized",
    "silent",
    "bad_subpackage",
    "short_kinematics",
    "no_kinematics",
    "close",
    "no_cartesian",
)
"""Behaviours of :class:`SimUrController` (``normal`` is a healthy controller)."""


def build_version_message(major: int = 5, minor: int = 8, bugfix: int = 0, build: int = 0) -> bytes:
    """A ROBOT_MESSAGE (type 20) version message as the controller sends first on connect."""
    name = b"URControl"
    date = b"01-01-2026, 00:00:00"
    payload = (
        struct.pack(">QbB", 0, -1, 3)
        + struct.pack(">B", len(name))
        + name
        + struct.pack(">BBii", major, minor, bugfix, build)
        + date
    )
    return encode_message(20, payload)


def build_robot_state(
    dh: DHParameters,
    calibration_status: int = 2,
    *,
    include_kinematics: bool = True,
    kinematics_size: int = 225,
    q_rad: tuple[float, ...] | None = None,
    include_cartesian: bool = True,
    robot_mode: RobotModeSample | None = None,
) -> bytes:
    """A complete RobotState message (type 16) with the URSim sub-package sequence.

    Args:
        dh: DH parameters reported in KinematicsInfo.
        calibration_status: KinematicsInfo ``calibration_status``.
        include_kinematics: Leave KinematicsInfo out (pre-3.6 CB3 software).
        kinematics_size: Size of the KinematicsInfo sub-package (< 225 makes it truncated, > 225 over-long).
        q_rad: Joint positions to report; Joint data and CartesianInfo (base → flange from the DH FK, zero
            TCP offset) are then filled in, otherwise they are zero-filled.
        include_cartesian: Leave CartesianInfo out (a fault: the pose a verification needs never arrives).
        robot_mode: RobotModeData to report (default: a powered, running arm, timestamp 0).

    Returns:
        The framed message (1386 bytes for the default layout).
    """
    subs = []
    for sub_type, size in ROBOT_STATE_LAYOUT:
        if sub_type == 4 and not include_cartesian:
            continue
        if sub_type == 0:
            subs.append(encode_robot_mode_data(robot_mode or RobotModeSample()))
            continue
        if sub_type == 5:
            if not include_kinematics:
                continue
            kin = encode_kinematics_info(dh, calibration_status)
            if kinematics_size < len(kin):
                body = kin[5:kinematics_size]
            else:
                body = kin[5:] + bytes(kinematics_size - len(kin))
            subs.append(encode_subpackage(5, body))
        elif sub_type == 1 and q_rad is not None:
            subs.append(encode_joint_data(q_rad))
        elif sub_type == 4 and q_rad is not None:
            T = fk_dh(dh, list(q_rad))
            xyz = (float(T[0, 3]), float(T[1, 3]), float(T[2, 3]))
            rv = rotvec_from_matrix(T[:3, :3])
            subs.append(encode_cartesian_info(xyz, (float(rv[0]), float(rv[1]), float(rv[2]))))
        else:
            subs.append(encode_subpackage(sub_type, bytes(size - 5)))
    return encode_message(16, b"".join(subs))


class SimUrController(StartsOnEnter):
    """Loopback primary-interface server (context manager).

    Example:
        >>> with SimUrController(nominal_dh("ur10e")) as sim:  # doctest: +SKIP
        ...     info = PrimaryClient(*sim.address, timeout_s=2).read_kinematics()

    Args:
        dh: DH reported in KinematicsInfo.
        calibration_status: Reported status (2 = linearised).
        mode: One of :data:`FAULT_MODES`.
        rate_hz: RobotState rate (10 Hz like the real controller).
        host: Bind address (loopback by default).
        port: Bind port (0 = a free port; see :attr:`address`).
        moving: Report a different joint configuration in every RobotState (with the matching base → flange
            CartesianInfo from the DH FK), for ``robocal ur verify --host``.
        arm: The arm's mode reported in RobotModeData (shared with a dashboard server; default: a new
            :class:`UrArmState`, powered and running).
    """

    def __init__(
        self,
        dh: DHParameters,
        *,
        calibration_status: int = 2,
        mode: str = "normal",
        rate_hz: float = 10.0,
        host: str = "127.0.0.1",
        port: int = 0,
        moving: bool = True,
        arm: UrArmState | None = None,
    ) -> None:
        if mode not in FAULT_MODES:
            raise ValueError(f"unknown simulator mode {mode!r}; valid: {', '.join(FAULT_MODES)}")
        self.dh = dh
        self.calibration_status = calibration_status
        self.mode = mode
        self.moving = moving
        self.arm = arm if arm is not None else UrArmState()
        self.period_s = 1.0 / rate_hz
        self._stop = threading.Event()
        self._listener = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
        self._listener.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        self._listener.bind((host, port))
        self._listener.listen(128)  # a burst of clients waits in the backlog instead of retrying its SYN
        self._listener.settimeout(0.05)
        self._threads: list[threading.Thread] = []
        self._clients: list[socket.socket] = []
        self._lock = threading.Lock()
        self.connections = 0

    @property
    def address(self) -> tuple[str, int]:
        """``(host, port)`` the server listens on."""
        host, port = self._listener.getsockname()[:2]
        return str(host), int(port)

    def start(self) -> SimUrController:
        """Start accepting connections in a background thread."""
        t = threading.Thread(target=self._accept_loop, name="sim-ur-accept", daemon=True)
        self._threads.append(t)
        t.start()
        return self

    def stop(self, timeout_s: float = 2.0) -> None:
        """Stop the server and close every connection (threads joined with a timeout)."""
        self._stop.set()
        with self._lock:
            clients = list(self._clients)
            threads = list(self._threads)
        for c in clients:
            with contextlib.suppress(OSError):
                c.shutdown(socket.SHUT_RDWR)
        for t in threads:
            t.join(timeout_s)
        with contextlib.suppress(OSError):
            self._listener.close()

    @property
    def open_connections(self) -> int:
        """Connections being served now (a finished one is released: its socket closed, its thread ended)."""
        with self._lock:
            return len(self._clients)

    def _accept_loop(self) -> None:
        accept_loop(self._listener, self._stop, self._accepted)

    def _accepted(self, conn: socket.socket) -> None:
        t = threading.Thread(target=self._serve_and_release, args=(conn,), name="sim-ur-client", daemon=True)
        with self._lock:
            self._clients.append(conn)
            self._threads.append(t)
            self.connections += 1
        t.start()

    def _serve_and_release(self, conn: socket.socket) -> None:
        try:
            self._serve(conn)
        finally:
            with contextlib.suppress(OSError):
                conn.close()
            with self._lock:
                self._clients.remove(conn)
                self._threads.remove(threading.current_thread())

    def _idle(self, conn: socket.socket, seconds: float) -> bool:
        """Wait ``seconds`` (less once stopped) reading what the client sends; False once it closed or failed.

        A client that hangs up is noticed now, not at the next failed send.
        """
        end = time.monotonic() + seconds
        try:
            while not self._stop.is_set():
                left = end - time.monotonic()
                if left <= 0:
                    return True
                conn.settimeout(min(left, 0.2))
                try:
                    if not conn.recv(4096):  # what a client sends (URScript) is read and dropped
                        return False
                except TimeoutError:
                    continue
                except OSError:
                    return False
            return False
        finally:
            with contextlib.suppress(OSError):
                conn.settimeout(1.0)  # sends wait up to a second for a slow reader

    def _send(self, conn: socket.socket, data: bytes) -> bool:
        try:
            conn.sendall(data)
            return True
        except OSError:
            return False

    def _serve(self, conn: socket.socket) -> None:
        conn.settimeout(1.0)
        mode = self.mode
        if mode == "silent":  # until the client hangs up or the server stops
            self._idle(conn, math.inf)
            return
        if mode == "close":
            return
        if mode == "garbage":
            self._send(conn, b"HTTP/1.1 400 Bad Request\r\nContent-Length: 0\r\n\r\n")
            self._stop.wait(0.5)
            return
        if not self._send(conn, build_version_message()):
            return
        if mode == "oversized":
            self._send(conn, struct.pack(">iB", 0x7FFFFFFF, 16) + bytes(64))
            self._stop.wait(0.5)
            return
        state = build_robot_state(
            self.dh,
            self.calibration_status,
            include_kinematics=mode != "no_kinematics",
            kinematics_size=100 if mode == "short_kinematics" else 225,
            robot_mode=self.arm.sample(),
        )
        if mode == "truncated":
            self._send(conn, state[: len(state) // 2])
            return
        if mode == "bad_subpackage":
            bad = bytearray(state)
            struct.pack_into(">I", bad, 5, 5000)  # first sub-package claims more than the message holds
            state = bytes(bad)
        modbus = encode_message(5, bytes(12))  # top-level type 5 (MODBUS_INFO), not KinematicsInfo
        next_t = time.monotonic()
        tick = 0
        while not self._stop.is_set():
            if mode in ("normal", "no_cartesian"):  # the mode follows the dashboard; the joints move
                q = tuple(1.5 * math.sin(0.37 * tick + 1.1 * i) for i in range(6)) if self.moving else None
                state = build_robot_state(
                    self.dh,
                    self.calibration_status,
                    q_rad=q,
                    include_cartesian=mode == "normal",
                    robot_mode=self.arm.sample(),
                )
            tick += 1
            if not self._send(conn, modbus + state):
                return
            next_t += self.period_s
            if not self._idle(conn, max(0.0, next_t - time.monotonic())):
                return
