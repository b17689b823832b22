"""One LeRobot arm read for ``health watch``, read-only.

SYNC_READ of ``Present_Position``, in radians about the middle of the calibration file's recorded range (physical
degrees: 4096 counts a turn, drive mode honoured).
"""

from __future__ import annotations

import contextlib
import math
from collections.abc import Iterator, Mapping
from pathlib import Path
from typing import Any

import numpy as np

from ...core.arrays import FloatArray
from ...core.lerobot import MotorCalibration, RobotSpec

__all__ = ["UNLIMITED_RAD", "ArmReader", "open_reader"]

UNLIMITED_RAD = 1e6
"""The "stop" of a joint that turns without one (a full-turn LeRobot joint, unwrapped)."""


class ArmReader:
    """Reads one arm's joints; its stops are the recorded range, a full-turn joint is followed across the seam.

    Attributes:
        names: Motor names, bus order.
        lower_rad: Lower end of each recorded range, rad (−:data:`UNLIMITED_RAD` for a full-turn joint).
        upper_rad: Upper end, rad.
    """

    def __init__(self, bus: Any, spec: RobotSpec, cals: Mapping[str, MotorCalibration]) -> None:
        """The arm's calibration in bus order and the conversion of its ends."""
        self._bus = bus
        self.names = spec.motor_names
        self._order = [cals[n] for n in self.names]
        self._ids = [m.motor_id for m in spec.motors]
        self._drive = spec.vendor_spec.applies_drive_mode_in_software
        ends = self._degrees(
            np.array([[c.range_min for c in self._order], [c.range_max for c in self._order]])
        )
        self._full = np.array([n in spec.full_turn for n in self.names])
        self.lower_rad = tuple(
            -UNLIMITED_RAD if f else math.radians(min(a, b))
            for f, a, b in zip(self._full, *ends, strict=True)
        )
        self.upper_rad = tuple(
            UNLIMITED_RAD if f else math.radians(max(a, b)) for f, a, b in zip(self._full, *ends, strict=True)
        )
        self._turn_rad = np.zeros(len(self.names))
        self._last = np.full(len(self.names), np.nan)

    def _degrees(self, raw: Any) -> FloatArray:
        from ...core.lerobot import normalize

        out: FloatArray = normalize(
            np.asarray(raw, dtype=np.float64),
            self._order,
            "degrees",
            apply_drive_mode=self._drive,
            convention="physical",
        )
        return out

    def read(self) -> FloatArray:
        """The joints now, rad, shape ``(N,)``."""
        raw = self._bus.sync_read("Present_Position", self._ids)
        q: FloatArray = np.radians(self._degrees([raw[i] for i in self._ids]))
        if self._full.any():  # a full-turn joint crosses its wrap: follow it across (it has no stops)
            jump = np.where(self._full & np.isfinite(self._last), q - self._last, 0.0)
            self._turn_rad -= 2 * math.pi * np.round(jump / (2 * math.pi))
            self._last = q.copy()
            q = q + self._turn_rad
        return q


@contextlib.contextmanager
def open_reader(
    robot: str,
    port: str,
    robot_id: str | None,
    calibration_dir: Path | None,
    calibration_file: Path | None,
    flag: str = "--lerobot-port",
) -> Iterator[ArmReader]:
    """Open an arm for reading (``sim``: a simulated arm, given the calibration first; nothing else is written).

    ``flag``: the option that gave ``port`` (``--lerobot-port``, ``--leader-port``), for the messages.
    """
    from ..lerobot import calibration_file as find_file
    from ..lerobot import open_arm, read_calibration_file, require_motors, restore, robot_spec

    spec = robot_spec(robot)
    path, _note = find_file(spec, robot_id, calibration_dir, calibration_file)
    cals = read_calibration_file(path)
    require_motors(spec, cals, path)
    with open_arm(spec, port, flag) as (bus, arm):
        if (
            arm is not None
        ):  # the simulated arm starts uncalibrated: give it this calibration (simulator only)
            restore(bus, spec, cals)
        yield ArmReader(bus, spec, cals)
