"""One motor's current-scheme LeRobot calibration (the values of LeRobot's calibration JSON) and its checks."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

from ...errors import InvalidCalibrationError

__all__ = ["MotorCalibration", "ranges_beyond_one_turn"]


@dataclass(frozen=True)
class MotorCalibration:
    """One motor's current-scheme LeRobot calibration (the values of LeRobot's calibration JSON).

    Attributes:
        id: Bus id of the motor.
        drive_mode: 0 or 1 (1 = inverted; Feetech in software, Dynamixel in the Drive_Mode register).
        homing_offset: Homing_Offset register value, ticks (signed).
        range_min: Min_Position_Limit, ticks.
        range_max: Max_Position_Limit, ticks.
    """

    id: int
    drive_mode: int
    homing_offset: int
    range_min: int
    range_max: int

    def __post_init__(self) -> None:
        for field in ("id", "drive_mode", "homing_offset", "range_min", "range_max"):
            value = getattr(self, field)
            if isinstance(value, bool) or not isinstance(value, (int, np.integer)):
                raise InvalidCalibrationError(f"MotorCalibration.{field} is {value!r}; expected an int")
            object.__setattr__(self, field, int(value))


def ranges_beyond_one_turn(
    cals: Mapping[str, MotorCalibration], *, resolution: int = 4096, vendor: str = "feetech"
) -> list[str]:
    """One warning per motor whose ``range_min..range_max`` lies outside one turn ``0..resolution − 1``.

    A single-turn servo (Feetech STS/SMS; Dynamixel X in position mode) never reports a Present_Position
    outside ``0..resolution − 1``, and its Min/Max_Position_Limit registers hold positions of that turn. LeRobot
    0.6.1 does not check this: it loads such a file, writes the values to the limit registers as they are and
    normalises with them, so the part of the range beyond the turn is never reached (a RANGE_0_100 gripper with
    range 3441..4837 tops out at 47 %). robocal accepts the file the same way but names every such motor.

    Args:
        cals: Motor name → calibration.
        resolution: Ticks per turn (4096).
        vendor: ``"feetech"`` or ``"dynamixel"`` (only used in the message).

    Returns:
        ``"motor 'NAME' (id N): range_min..range_max LO..HI is beyond one turn ..."`` per motor, in file order.
    """
    out = []
    top = resolution - 1
    for name, c in cals.items():
        if c.range_min >= 0 and c.range_max <= top:
            continue
        span = c.range_max - c.range_min
        reach = ""
        if span > 0 and c.range_min <= top and c.range_max >= 0:
            lo_pct = 100.0 * (max(c.range_min, 0) - c.range_min) / span
            hi_pct = 100.0 * (min(c.range_max, top) - c.range_min) / span
            reach = f"; positions of one turn only cover {lo_pct:.0f}..{hi_pct:.0f} % of it"
        out.append(
            f"motor {name!r} (id {c.id}): range_min..range_max {c.range_min}..{c.range_max} is beyond one turn "
            f"of a {resolution}-tick {vendor} servo (0..{top}){reach}; LeRobot 0.6.1 accepts it unchecked; "
            "recalibrate the motor (or re-home the range)"
        )
    return out
