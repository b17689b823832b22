"""The simulated UR arm's mode (power, brakes, program, safety) that every port of the controller reports.

One :class:`UrArmState` is shared by the primary/secondary streams (RobotModeData, sub-type 0) and the dashboard
server (29999): ``power off`` on the dashboard shows up as robot mode 3 in the next RobotState. The arm starts
as an arm that is on and running: robot mode 7 (RUNNING), powered, enabled, no stop, speed fractions 1.0.

RobotModeData layout (5.x, 47 bytes with its header), as URCL's ``robot_mode_data.cpp`` and python-urx's
``ursecmon.py`` read it: ``uint32 size, uint8 type 0, uint64 timestamp, 7 × bool (real robot connected,
enabled, power on, emergency stopped, protective stopped, program running, program paused), int8 robot mode,
uint8 control mode, 3 × double (target speed fraction, speed scaling, target speed fraction limit), uint8
reserved``. python-urx picks its layout by that size (47 → 3.5) and calls the arm running only with mode 7.
"""

from __future__ import annotations

import struct
import threading
import time
from dataclasses import dataclass, replace

from ...errors import ProtocolError
from ..ur_primary import encode_subpackage

__all__ = [
    "ROBOT_MODES",
    "ROBOT_MODE_DATA_SIZE",
    "RobotModeSample",
    "UrArmState",
    "encode_robot_mode_data",
    "parse_robot_mode_data",
]

ROBOT_MODES: dict[str, int] = {
    "NO_CONTROLLER": -1,
    "DISCONNECTED": 0,
    "CONFIRM_SAFETY": 1,
    "BOOTING": 2,
    "POWER_OFF": 3,
    "POWER_ON": 4,
    "IDLE": 5,
    "BACKDRIVE": 6,
    "RUNNING": 7,
}
"""Robot mode names (as the dashboard says them) and numbers (as RobotModeData and RTDE carry them)."""

_MODE_NAMES = {v: k for k, v in ROBOT_MODES.items()}
_BODY = struct.Struct(">Q???????bBdddB")
ROBOT_MODE_DATA_SIZE = 5 + _BODY.size
"""47: the size python-urx reads as the 3.5+ layout."""


@dataclass(frozen=True)
class RobotModeSample:
    """The content of one RobotModeData sub-package.

    Attributes:
        timestamp: Controller timestamp (the simulator counts microseconds since it started).
        real_robot_connected / real_robot_enabled / robot_power_on: Arm flags.
        emergency_stopped / protective_stopped: Stops (never set by the simulator today).
        program_running / program_paused: Program flags (follow the dashboard's play / pause / stop).
        robot_mode: A value of :data:`ROBOT_MODES` (7 = RUNNING).
        control_mode: 0 (position control; the simulator never changes it).
        target_speed_fraction / speed_scaling / target_speed_fraction_limit: Speed slider fractions, 0–1.
    """

    timestamp: int = 0
    real_robot_connected: bool = True
    real_robot_enabled: bool = True
    robot_power_on: bool = True
    emergency_stopped: bool = False
    protective_stopped: bool = False
    program_running: bool = False
    program_paused: bool = False
    robot_mode: int = ROBOT_MODES["RUNNING"]
    control_mode: int = 0
    target_speed_fraction: float = 1.0
    speed_scaling: float = 1.0
    target_speed_fraction_limit: float = 1.0

    @property
    def robot_mode_name(self) -> str:
        """The dashboard's name of :attr:`robot_mode` (``RUNNING`` …)."""
        return _MODE_NAMES.get(self.robot_mode, str(self.robot_mode))


def encode_robot_mode_data(sample: RobotModeSample) -> bytes:
    """Encode a RobotModeData sub-package (47 bytes, header included)."""
    s = sample
    body = _BODY.pack(
        s.timestamp,
        s.real_robot_connected,
        s.real_robot_enabled,
        s.robot_power_on,
        s.emergency_stopped,
        s.protective_stopped,
        s.program_running,
        s.program_paused,
        s.robot_mode,
        s.control_mode,
        s.target_speed_fraction,
        s.speed_scaling,
        s.target_speed_fraction_limit,
        0,
    )
    return encode_subpackage(0, body)


def parse_robot_mode_data(sub: bytes) -> RobotModeSample:
    """Decode a 5.x RobotModeData sub-package (header included).

    Raises:
        ProtocolError: Not sub-type 0, or not the 47-byte layout.
    """
    if len(sub) != ROBOT_MODE_DATA_SIZE or sub[4] != 0:
        raise ProtocolError(
            f"RobotModeData: expected sub-type 0 of {ROBOT_MODE_DATA_SIZE} bytes, "
            f"got type {sub[4] if len(sub) > 4 else '?'} of {len(sub)} bytes"
        )
    v = _BODY.unpack_from(sub, 5)
    return RobotModeSample(*v[:13])


class UrArmState:
    """The arm's mode, shared by the controller's servers (thread-safe).

    Transitions (the dashboard's commands; see docs/sim.md for what is assumed): ``power_on`` POWER_OFF →
    IDLE, ``brake_release`` IDLE → RUNNING, ``power_off`` any → POWER_OFF (a program stops). A program plays
    only while RUNNING with a program loaded.

    Args:
        model: Robot model the dashboard names (``UR10`` …).
        serial_number: Serial number the dashboard reports.
    """

    def __init__(self, model: str = "UR10", serial_number: str = "20235500001") -> None:
        self.model = model
        self.serial_number = serial_number
        self._lock = threading.Lock()
        self._t0 = time.monotonic()
        self._mode = RobotModeSample()
        self.program: str | None = None
        self.safety_mode = "NORMAL"

    def sample(self) -> RobotModeSample:
        """RobotModeData now (timestamp in microseconds since the simulator started)."""
        with self._lock:
            return replace(self._mode, timestamp=int((time.monotonic() - self._t0) * 1e6))

    @property
    def robot_mode_name(self) -> str:
        """Robot mode name, e.g. ``RUNNING``."""
        with self._lock:
            return self._mode.robot_mode_name

    @property
    def program_state(self) -> str:
        """``STOPPED``, ``PLAYING`` or ``PAUSED``."""
        with self._lock:
            m = self._mode
        return "PLAYING" if m.program_running else "PAUSED" if m.program_paused else "STOPPED"

    def _set(self, **changes: object) -> None:
        self._mode = replace(self._mode, **changes)  # type: ignore[arg-type]

    def power_on(self) -> None:
        """POWER_OFF → IDLE (through POWER_ON, instantly); other modes are left alone."""
        with self._lock:
            if self._mode.robot_mode == ROBOT_MODES["POWER_OFF"]:
                self._set(robot_mode=ROBOT_MODES["IDLE"], robot_power_on=True, real_robot_enabled=True)

    def power_off(self) -> None:
        """Any mode → POWER_OFF; a running or paused program stops."""
        with self._lock:
            self._set(
                robot_mode=ROBOT_MODES["POWER_OFF"],
                robot_power_on=False,
                real_robot_enabled=False,
                program_running=False,
                program_paused=False,
            )

    def brake_release(self) -> None:
        """IDLE → RUNNING; other modes are left alone."""
        with self._lock:
            if self._mode.robot_mode == ROBOT_MODES["IDLE"]:
                self._set(robot_mode=ROBOT_MODES["RUNNING"])

    def play(self) -> bool:
        """Start (or resume) the loaded program; False when not RUNNING or nothing is loaded."""
        with self._lock:
            if self.program is None or self._mode.robot_mode != ROBOT_MODES["RUNNING"]:
                return False
            self._set(program_running=True, program_paused=False)
            return True

    def pause(self) -> bool:
        """Pause a playing program; False when none plays."""
        with self._lock:
            if not self._mode.program_running:
                return False
            self._set(program_running=False, program_paused=True)
            return True

    def stop_program(self) -> None:
        """Stop the program (playing, paused or not)."""
        with self._lock:
            self._set(program_running=False, program_paused=False)

    def load(self, program: str) -> None:
        """Load a program (stops the one that plays)."""
        with self._lock:
            self.program = program
            self._set(program_running=False, program_paused=False)
