"""LeRobot conventions for dataset values (current normalised scheme and legacy degrees/percent)."""

from __future__ import annotations

from ._lerobot import LegacyConvention as LegacyConvention
from ._lerobot import LeRobotConvention as LeRobotConvention
from ._lerobot import MotorFamily as MotorFamily
from ._lerobot import load_convention as load_convention
from ._lerobot import motor_family_for_robot as motor_family_for_robot
from ._lerobot import preset_modes as preset_modes

__all__ = [
    "LeRobotConvention",
    "LegacyConvention",
    "MotorFamily",
    "load_convention",
    "motor_family_for_robot",
    "preset_modes",
]
