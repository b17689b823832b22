"""robocal.core.wrap_range: the one wrap-aware range tracker (sweep in rad, LeRobot in ticks)."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from robocal.core import sweep
from robocal.core.wrap_range import RangeTracker
from robocal.errors import InvalidCalibrationError


def test_the_sweep_uses_the_same_tracker() -> None:
    assert sweep.RangeTracker is RangeTracker


def test_half_a_period_step_counts_as_going_down_in_both_paths() -> None:
    # LeRobot's rule: step = (d + half) mod period - half, so +2048 and -2048 both unwrap to -2048
    one = RangeTracker(1, period=4096, units="ticks")
    block = RangeTracker(1, period=4096, units="ticks")
    readings = [1000, 3048, 1000, 3048]
    for r in readings:
        one.update([r])
    block.update_many(np.array(readings, dtype=float)[:, None])
    for tr in (one, block):
        assert (tr.minimum[0], tr.maximum[0]) == (1000 - 3 * 2048, 1000)
        assert tr.current[0] == 1000 - 3 * 2048


def test_ticks_extremes_as_read_and_unwrapped() -> None:
    tr = RangeTracker(2, period=4096, units="ticks")
    tr.update_many(np.array([[4000, 10], [4090, 4080], [30, 20]], dtype=float))
    assert tr.raw_minimum.tolist() == [30, 10] and tr.raw_maximum.tolist() == [4090, 4080]
    assert tr.minimum.tolist() == [4000, -16] and tr.maximum.tolist() == [4126, 20]
    assert tr.sweep.tolist() == [126, 36]


def test_the_period_is_named_with_its_units() -> None:
    with pytest.raises(InvalidCalibrationError, match=r"period -4096(\.0)? ticks must be finite and > 0"):
        RangeTracker(1, period=-4096, units="ticks")
    empty = RangeTracker(1, period=4096, units="ticks")
    assert np.isnan(empty.raw_minimum[0]) and np.isnan(empty.raw_maximum[0])


@given(st.lists(st.integers(0, 4095), min_size=1, max_size=40))
def test_integer_ticks_per_sample_equals_block_exactly(readings: list[int]) -> None:
    a = RangeTracker(1, period=4096, units="ticks")
    b = RangeTracker(1, period=4096, units="ticks")
    for r in readings:
        a.update([r])
    b.update_many(np.array(readings, dtype=float)[:, None])
    assert (a.minimum[0], a.maximum[0], a.current[0]) == (b.minimum[0], b.maximum[0], b.current[0])
    assert (a.raw_minimum[0], a.raw_maximum[0]) == (min(readings), max(readings))
