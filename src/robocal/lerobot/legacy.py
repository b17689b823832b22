"""LeRobot legacy calibration (2024 → 2025-06): files, ``apply_calibration`` / ``revert_calibration``.

``cal`` is a :class:`~robocal.core.lerobot.LegacyCalibration` (the six arrays of the legacy JSON). Only
re-exports under LeRobot's names: the math lives in :mod:`robocal.core.lerobot.legacy`, the files in
:mod:`robocal.formats.lerobot`.
"""

from __future__ import annotations

from ..core.lerobot.legacy import (
    LegacyCalibration,
    apply_calibration,
    degree_joint_map,
    revert_calibration,
    to_robot_calibration,
)
from ..core.lerobot.legacy import autocorrect_legacy as autocorrect_calibration
from ..core.lerobot.legacy import degrees_to_steps as convert_degrees_to_steps
from ..core.lerobot.legacy import legacy_calibration_from_poses as calibration_from_poses
from ..formats.lerobot import read_legacy, write_legacy

__all__ = [
    "LegacyCalibration",
    "apply_calibration",
    "autocorrect_calibration",
    "calibration_from_poses",
    "convert_degrees_to_steps",
    "degree_joint_map",
    "read_legacy",
    "revert_calibration",
    "to_robot_calibration",
    "write_legacy",
]
