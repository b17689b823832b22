"""LeRobot compatibility: current-scheme calibration values, normalisation and files (the public facade).

>>> cal = MotorCalibration(id=1, drive_mode=0, homing_offset=0, range_min=1000, range_max=3000)
>>> float(normalize(1500, cal, "range_m100_100"))
-50.0

``compat="lerobot"`` is bit-identical to LeRobot 0.6.1; ``compat="exact"`` rounds so raw → normalised → raw
is the identity, and changes nothing else. ``convention="physical"`` (instead of LeRobot's default) makes
DEGREES true joint degrees: 4096 ticks per turn and ``drive_mode`` honoured (see ``docs/lerobot.md``).

Only re-exports: the logic lives in :mod:`robocal.core.lerobot` (values, normalisation), and
:mod:`robocal.formats.lerobot` (files, calibration paths); nothing below robocal imports this package.
"""

from __future__ import annotations

from ..core.lerobot.calibration import MotorCalibration
from ..core.lerobot.normalisation import NormMode, normalize, unnormalize
from ..formats.lerobot import KINDS, calibration_path, default_calibration_root
from ..formats.lerobot import read_current as read_calibration
from ..formats.lerobot import write_current as write_calibration

__all__ = [
    "KINDS",
    "MotorCalibration",
    "NormMode",
    "calibration_path",
    "default_calibration_root",
    "normalize",
    "read_calibration",
    "unnormalize",
    "write_calibration",
]
