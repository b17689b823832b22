"""A torque-limited move that breakaway friction holds short of its target counts as arrived; a block does not."""

from __future__ import annotations

import math

import pytest

from robocal.workflows.autocal.job import AutoCalAbortedError
from robocal.workflows.autocal.joint import FRICTION_SETTLE_S, move_to

from .plant import Plant, PlantDriver

CAP_NM = 1.0
MAX_LAG_RAD = math.radians(3.0)


def _sticky(**kw: float) -> Plant:
    # the drive law of the Robstride driver: kp = cap / max_lag, so the pull reaches the cap at max_lag
    return Plant(q_lo=-3.0, q_hi=3.0, kp=CAP_NM / MAX_LAG_RAD, stiction=0.8 * CAP_NM, noise_rad=0.0, **kw)


def test_small_move_from_rest_on_a_sticky_joint_arrives_where_friction_holds_it() -> None:
    plant = _sticky()
    target = math.radians(1.9)  # kp·1.9° = 0.63 cap < breakaway 0.8 cap: the joint never leaves 0
    s, stalled = move_to(PlantDriver("j", plant), target, math.radians(20.0), CAP_NM, MAX_LAG_RAD)
    assert not stalled
    assert plant.q == pytest.approx(0.0, abs=1e-9)
    assert abs(s.q_rad - target) == pytest.approx(target, abs=math.radians(0.1))
    assert s.t_s >= FRICTION_SETTLE_S  # not before it has rested that long
    assert s.t_s < 3.0  # well inside the move's time bound (distance/speed + 3 s)


def test_a_joint_held_further_than_the_lag_is_still_blocked() -> None:
    plant = _sticky(obstacle=0.2, k_hi=2000.0)  # a block 11.5° short of the target
    with pytest.raises(AutoCalAbortedError, match=r"could not reach 20\.0° .*blocked\?"):
        move_to(PlantDriver("j", plant), math.radians(20.0), math.radians(20.0), CAP_NM, MAX_LAG_RAD)
