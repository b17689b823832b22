"""Simulated UR real-time interface (TCP 30003): a fixed-size state message at 500 Hz.

Each message is ``int32 BE size`` (1116) and 139 big-endian doubles in the layout python-urx's ``urrtmon.py``
reads for 5.9 (``rtstruct5_9``). Filled in: Time (0), q_target (1–6), q_actual (31–36), Tool_vector_actual
(55–60) and Tool_vector_target (73–78, the TCP pose python-urx reports) from the DH forward kinematics,
robot_mode (94) from the shared :class:`UrArmState`, safety_mode (101) and safety_status (138) 1 (NORMAL),
program_state (131); every other value is 0. Sources and assumptions: docs/sim.md (UR section).
"""

from __future__ import annotations

import math
import socket
import struct
import time

from ...core.dh import DHParameters, fk_dh
from ...core.lifecycle import StartsOnEnter
from ...core.se3 import rotvec_from_matrix
from ._sockets import LoopbackServer
from .ur_arm_state import UrArmState

__all__ = ["REALTIME_DOUBLES", "REALTIME_MESSAGE_SIZE", "SimUrRealtime", "build_realtime_message", "joint_path"]

REALTIME_DOUBLES = 139
"""Doubles in a 5.9 real-time message."""
REALTIME_MESSAGE_SIZE = 4 + 8 * REALTIME_DOUBLES
"""1116 bytes, the size field included."""

_MESSAGE = struct.Struct(f">i{REALTIME_DOUBLES}d")
_TIME, _Q_TARGET, _Q_ACTUAL, _TOOL_ACTUAL, _TOOL_TARGET = 0, 1, 31, 55, 73
_ROBOT_MODE, _JOINT_MODES, _SAFETY_MODE, _PROGRAM_STATE, _SAFETY_STATUS = 94, 95, 101, 131, 138
_JOINT_RUNNING = 253.0  # joint mode of a running joint (assumed, as URCL's JOINT_RUNNING_MODE)


def joint_path(t_s: float) -> tuple[float, ...]:
    """The joint angles (rad) of the moving simulated arm at ``t_s`` seconds (the primary stream's path)."""
    tick = 10.0 * t_s
    return tuple(1.5 * math.sin(0.37 * tick + 1.1 * i) for i in range(6))


def build_realtime_message(
    dh: DHParameters,
    t_s: float,
    q_rad: tuple[float, ...],
    *,
    robot_mode: int = 7,
    program_running: bool = False,
) -> bytes:
    """One real-time message (1116 bytes).

    Args:
        dh: DH model whose forward kinematics gives the TCP pose (flange, zero TCP offset).
        t_s: Controller time, seconds.
        q_rad: Six joint angles, target and actual.
        robot_mode: Robot mode (7 = RUNNING).
        program_running: Program state 2 (playing) instead of 1 (stopped).
    """
    values = [0.0] * REALTIME_DOUBLES
    values[_TIME] = t_s
    T = fk_dh(dh, list(q_rad))
    rv = rotvec_from_matrix(T[:3, :3])
    pose = (float(T[0, 3]), float(T[1, 3]), float(T[2, 3]), float(rv[0]), float(rv[1]), float(rv[2]))
    for start, six in ((_Q_TARGET, q_rad), (_Q_ACTUAL, q_rad), (_TOOL_ACTUAL, pose), (_TOOL_TARGET, pose)):
        values[start : start + 6] = [float(v) for v in six]
    values[_JOINT_MODES : _JOINT_MODES + 6] = [_JOINT_RUNNING] * 6
    values[_ROBOT_MODE] = float(robot_mode)
    values[_SAFETY_MODE] = values[_SAFETY_STATUS] = 1.0
    values[_PROGRAM_STATE] = 2.0 if program_running else 1.0
    return _MESSAGE.pack(REALTIME_MESSAGE_SIZE, *values)


class SimUrRealtime(LoopbackServer, StartsOnEnter):
    """Loopback real-time server: every client gets the arm's state at ``rate_hz`` (context manager).

    Args:
        dh: DH model of the arm.
        arm: The arm's mode (shared with the other ports).
        host: Bind address.
        port: Bind port (0 = a free port).
        rate_hz: Message rate (500 Hz like an e-Series; a late message is not made up for).
        moving: Joints follow :func:`joint_path`; otherwise they stay at zero.

    Raises:
        OSError: The address cannot be bound.
    """

    def __init__(
        self,
        dh: DHParameters,
        arm: UrArmState,
        *,
        host: str = "127.0.0.1",
        port: int = 0,
        rate_hz: float = 500.0,
        moving: bool = True,
    ) -> None:
        super().__init__(host=host, port=port, name="sim-ur-realtime")
        self.dh = dh
        self.arm = arm
        self.period_s = 1.0 / rate_hz
        self.moving = moving
        self._t0 = time.monotonic()

    def _serve(self, conn: socket.socket) -> None:
        conn.settimeout(1.0)  # a send waits up to a second for a slow reader
        next_t = time.monotonic()
        while not self.stopping:
            t_s = time.monotonic() - self._t0
            sample = self.arm.sample()
            q = joint_path(t_s) if self.moving else (0.0,) * 6
            conn.sendall(
                build_realtime_message(
                    self.dh, t_s, q, robot_mode=sample.robot_mode, program_running=sample.program_running
                )
            )
            next_t = max(next_t + self.period_s, time.monotonic())  # late: no burst to catch up
            if self.wait(max(0.0, next_t - time.monotonic())):
                return
