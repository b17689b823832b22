"""Where LeRobot and the follower's servo stop a teleoperated joint (:mod:`.teleop`'s sessions use them).

Range-mode clamps, the servo's position limits, the hand's scatter of a recorded range.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

import numpy as np

from ...core.arrays import FloatArray

if TYPE_CHECKING:
    from .teleop import TeleopArm

__all__ = ["SCATTER_DEG", "clamp_bounds_deg", "goal_limits_deg", "hand_scatter_deg"]

_INF = math.inf

SCATTER_DEG = 1.5
"""The largest hand scatter of a recorded range end short of its stop, degrees."""


def hand_scatter_deg(arm: TeleopArm, seed: int) -> tuple[FloatArray, FloatArray]:
    """How far short of its stops each arm's recorded range ends, per joint (``(J,)`` leader, follower).

    Uniform 0..:data:`SCATTER_DEG`, the same at both ends (so it adds no offset), drawn per session from its seed
    (leader's joints first); 0 where nothing is recorded between stops and for range-mode joints (the gripper:
    its values assume the profile's stops).
    """
    rng = np.random.default_rng(90_000 + seed)
    out = []
    for _arm in ("leader", "follower"):
        x = np.zeros(len(arm.joints))
        for j in range(len(arm.joints)):
            if arm.recorded(j) and arm.modes[j] == "degrees":
                x[j] = float(rng.uniform(0.0, SCATTER_DEG))
        out.append(x)
    return out[0], out[1]


def goal_limits_deg(
    arm: TeleopArm, offset_deg: FloatArray, scatter_deg: FloatArray, modes: tuple[str, ...], *, enforced: bool = True
) -> tuple[FloatArray, FloatArray]:
    """The follower servo's position limits in its reading frame, per joint (±inf where none is enforced).

    LeRobot writes the recorded range to ``Min/Max_Position_Limit``; a range recorded ``x`` short of both stops
    (the hand) and ``2·|e|`` short at one end (what makes a degree-mode offset ``e``) reads
    ``[lo + x + |e|, hi − x − |e|]``. A range-mode joint's range is the stops themselves.
    """
    lo, hi = np.full(len(arm.joints), -_INF), np.full(len(arm.joints), _INF)
    if not (enforced and arm.goal_limited):
        return lo, hi
    for j in range(len(arm.joints)):
        if not arm.recorded(j):
            continue
        inset = 0.0 if modes[j].startswith("range_") else scatter_deg[j] + abs(offset_deg[j])
        lo[j], hi[j] = arm.stop_lo_deg[j] + inset, arm.stop_hi_deg[j] - inset
    return lo, hi


def clamp_bounds_deg(arm: TeleopArm, modes: tuple[str, ...]) -> tuple[FloatArray, FloatArray]:
    """Per joint, the readings (degrees, each arm's own frame) LeRobot clamps a value to in ``modes``.

    A range mode clamps to the calibrated range (the profile's stops; a full-turn joint ±180°), degrees do not
    (±inf).

    Raises:
        ValueError: ``modes`` is not one mode per joint.
    """
    if len(modes) != len(arm.joints):
        raise ValueError(f"{len(modes)} modes for the {len(arm.joints)} joints of {arm.name}")
    lo, hi = np.full(len(modes), -_INF), np.full(len(modes), _INF)
    for j, mode in enumerate(modes):
        if mode.startswith("range_"):
            finite = math.isfinite(arm.stop_lo_deg[j])
            lo[j], hi[j] = (arm.stop_lo_deg[j], arm.stop_hi_deg[j]) if finite else (-180.0, 180.0)
    return lo, hi
