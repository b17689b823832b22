"""Sweep math in robocal.core.sweep: range tracker, bisection rule, diagnostics."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from robocal.core import RobotCalibration
from robocal.core.sweep import (
    RangeTracker,
    analyse_sweep,
    bisect_homing_offset,
    direction_from_motion,
    wrap_in_travel,
)
from robocal.core.sweep_result import CODES
from robocal.errors import InvalidCalibrationError, ShapeMismatchError

TWO_PI = 2 * math.pi


def test_codes_are_stable() -> None:
    assert CODES == (
        "ok",
        "not_swept",
        "no_overlap",
        "span_mismatch",
        "offset_large",
        "wrap_in_travel",
        "direction_flipped",
        "direction_unknown",  # appended: the codes keep their strings and order
        "wrong_side",  # appended with the one-sided procedure (issue 15)
    )


def test_bisection_golden_left_elbow() -> None:
    # left_elbow_pitch: dir -1, limits [-2.356, 0]; true offset 1.0 rad -> raw [1.0, 3.356], s = -raw
    h = bisect_homing_offset([-3.356], [-1.0], [-2.356], [0.0], [-1])
    assert h[0] == pytest.approx(1.0, abs=1e-12)


def test_tracker_plain_min_max() -> None:
    tr = RangeTracker(2)
    for row in ([0.1, -1.0], [0.5, -2.0], [-0.3, -1.5]):
        tr.update(row)
    np.testing.assert_allclose(tr.minimum, [-0.3, -2.0])
    np.testing.assert_allclose(tr.maximum, [0.5, -1.0])
    np.testing.assert_allclose(tr.sweep, [0.8, 1.0])
    assert tr.count.tolist() == [3, 3]


def test_tracker_unwraps_power_on_wrap() -> None:
    # a single-turn reading in [0, 2pi) that crosses 0: 0.3 -> 0.1 -> 6.2 (= -0.083) -> 5.9 (= -0.383)
    tr = RangeTracker(1)
    tr.update_many(np.array([[0.3], [0.1], [6.2], [5.9]]))
    assert tr.minimum[0] == pytest.approx(5.9 - TWO_PI)
    assert tr.maximum[0] == pytest.approx(0.3)
    assert tr.sweep[0] == pytest.approx(0.3 - (5.9 - TWO_PI))


def test_tracker_unwraps_4pi_runtime_wrap() -> None:
    # the type-2 position wraps at +-4pi: 12.5 -> -12.5 is a step of +0.066 rad
    four_pi = 4 * math.pi
    tr = RangeTracker(1)
    tr.update([12.5])
    tr.update([-12.5])
    assert tr.maximum[0] == pytest.approx(-12.5 + 2 * four_pi)
    assert tr.sweep[0] == pytest.approx(2 * four_pi - 25.0)


def test_tracker_ignores_nan_and_checks_shape() -> None:
    tr = RangeTracker(2)
    tr.update_many(np.array([[np.nan, 1.0], [0.2, np.nan], [0.4, 2.0]]))
    assert tr.count.tolist() == [2, 2]
    np.testing.assert_allclose(tr.minimum, [0.2, 1.0])
    np.testing.assert_allclose(tr.maximum, [0.4, 2.0])
    with pytest.raises(ShapeMismatchError, match=r"expected \(2,\)"):
        tr.update([1.0])
    with pytest.raises(InvalidCalibrationError, match="period"):
        RangeTracker(1, period=0.0)
    empty = RangeTracker(1)
    assert math.isnan(empty.minimum[0]) and empty.sweep[0] == 0.0


@given(
    start=st.floats(-3.0, 3.0),
    steps=st.lists(st.floats(-0.5, 0.5), min_size=1, max_size=200),
    wrap_lo=st.sampled_from([0.0, -math.pi]),
    chunk=st.integers(1, 50),
)
def test_tracker_invariant_wrapped_equals_true_range(
    start: float, steps: list[float], wrap_lo: float, chunk: int
) -> None:
    """Feeding the signal wrapped into one turn gives the true range, shifted by a whole number of turns."""
    true = start + np.concatenate([[0.0], np.cumsum(steps)])
    wrapped = np.mod(true - wrap_lo, TWO_PI) + wrap_lo
    tr = RangeTracker(1)
    for i in range(0, len(wrapped), chunk):
        tr.update_many(wrapped[i : i + chunk, None])
    shift = wrapped[0] - true[0]
    assert round(shift / TWO_PI) * TWO_PI == pytest.approx(shift, abs=1e-9)
    assert tr.minimum[0] == pytest.approx(true.min() + shift, abs=1e-9)
    assert tr.maximum[0] == pytest.approx(true.max() + shift, abs=1e-9)
    assert tr.sweep[0] == pytest.approx(true.max() - true.min(), abs=1e-9)


@given(
    h=st.floats(-3.0, 3.0),
    d=st.sampled_from([-1, 1]),
    lo=st.floats(-3.0, -0.1),
    width=st.floats(0.6, 3.9),
)
def test_bisection_recovers_offset_from_full_sweep(h: float, d: int, lo: float, width: float) -> None:
    up = lo + width
    s = d * (d * np.array([lo, up]) + h)  # identity frame of the two stops
    off = bisect_homing_offset(s.min(), s.max(), lo, up, d)
    assert float(off) == pytest.approx(h, abs=1e-9)


def test_wrap_in_travel_rule() -> None:
    # left_shoulder_pitch dir -1, [-3.142, 0.785]: raw travel h + [-0.785, 3.142]
    assert wrap_in_travel(0.5, -1, -3.142, 0.785, 0)  # raw [-0.285, 3.642] contains 0
    assert not wrap_in_travel(1.0, -1, -3.142, 0.785, 0)  # raw [0.215, 4.142]
    assert wrap_in_travel(1.0, -1, -3.142, 0.785, 1)  # contains pi
    assert not wrap_in_travel(-2.0, -1, -3.142, 0.785, 1)  # raw [-2.785, 1.142] inside (-pi, pi)
    got = wrap_in_travel([3.0, 3.0], [1, 1], [-0.5, -0.5], [0.5, 0.5], [0, 1])
    assert got.tolist() == [False, True]


def test_direction_from_motion() -> None:
    assert direction_from_motion(0.5) == 1
    assert direction_from_motion(-0.5) == -1
    assert direction_from_motion(0.05) == 0
    assert direction_from_motion(float("nan")) == 0


ELBOW = {"direction": [-1], "lower": [-2.356], "upper": [0.0]}


def one(smin: float, smax: float, **kw: object) -> tuple[str, ...]:
    res = analyse_sweep(["j"], ELBOW["direction"], ELBOW["lower"], ELBOW["upper"], [smin], [smax], **kw)  # type: ignore[arg-type]
    return res["j"].warnings


def test_every_code_constructed() -> None:
    assert one(-3.356, -1.0) == ()  # h = 1.0
    res = analyse_sweep(["j"], [-1], [-2.356], [0.0], [-3.356], [-1.0])
    assert res.ok and res["j"].status == "ok" and res["j"].homing_offset == pytest.approx(1.0)
    # not swept: prior kept
    res = analyse_sweep(["j"], [-1], [-2.356], [0.0], [-1.2], [-1.0], prior={"j": 0.7})
    j = res["j"]
    assert j.warnings == ("not_swept",) and j.kept_prior and j.homing_offset == 0.7
    assert j.previous_homing_offset == 0.7 and math.isnan(j.bisection_offset)
    # not swept without prior: no offset
    res = analyse_sweep(["j"], [-1], [-2.356], [0.0], [-1.2], [-1.0])
    assert res.missing_offsets == ("j",) and not res["j"].kept_prior
    # no overlap: s in [1.0, 3.356] entirely above the URDF range [-2.356, 0]
    assert "no_overlap" in one(1.0, 3.356)
    # span mismatch: stopped 0.3 rad short
    assert one(-3.056, -1.0) == ("span_mismatch",)
    # offset large: h = 3.5 -> s in [-5.856, -3.5]
    assert one(-5.856, -3.5) == ("no_overlap", "offset_large")
    # wrap in travel: h = 1.0 -> raw [1.0, 3.356] is fine with zero_sta 0, crosses pi with zero_sta 1;
    # h = -0.5 -> raw [-0.5, 1.856] crosses 0
    assert one(-3.356, -1.0, zero_sta=1) == ("wrap_in_travel",)
    assert one(-1.856, 0.5) == ("wrap_in_travel",)
    # direction flipped by the guided check
    assert one(-3.356, -1.0, direction_check={"j": -1}) == ("direction_flipped",)
    assert one(-3.356, -1.0, direction_check={"j": 1}) == ()


def test_report_shape() -> None:
    res = analyse_sweep(
        ["a", "b"], [-1, 1], [-2.356, -1.0], [0.0, 1.0], [-3.356, 0.0], [-1.0, 0.1], prior={"b": 2.0}
    )
    rep = res.to_report()
    assert list(rep) == ["joints"]
    assert rep["joints"]["a"] == {
        "sampled_min": -3.356,
        "sampled_max": -1.0,
        "sweep": pytest.approx(2.356),
        "homing_offset": pytest.approx(1.0),
        "previous_homing_offset": None,
        "kept_prior": False,
        "warnings": [],
    }
    assert rep["joints"]["b"]["kept_prior"] is True
    assert rep["joints"]["b"]["warnings"] == ["not_swept"]


def test_analyse_rejects_bad_arguments() -> None:
    with pytest.raises(ShapeMismatchError, match="lower"):
        analyse_sweep(["a", "b"], [1, 1], [0.0], [1.0, 1.0], [0, 0], [1, 1])
    with pytest.raises(InvalidCalibrationError, match="threshold"):
        analyse_sweep(["a"], [1], [0.0], [1.0], [0], [1], threshold_rad=-1.0)


def test_branch_selection_after_power_on_uses_robot_calibration() -> None:
    # offset computed on a branch where the elbow's raw travel is [-0.5, 1.856]; after power-on in [0, 2pi)
    # a pose at raw -0.2 reads 2pi - 0.2. unwrap_to_limits brings it back.
    cal = RobotCalibration(["elbow"], [-1], [-0.5])
    raw_power_on = np.array([TWO_PI - 0.2])
    fixed = cal.unwrap_to_limits(raw_power_on, [-2.356], [0.0])
    assert fixed[0] == pytest.approx(-0.2)
    assert cal.to_joint(fixed)[0] == pytest.approx(-0.3)


@given(
    rows=st.lists(
        st.lists(st.one_of(st.floats(-7.0, 7.0), st.just(float("nan"))), min_size=3, max_size=3),
        min_size=1,
        max_size=60,
    )
)
def test_tracker_per_sample_equals_block(rows: list[list[float]]) -> None:
    """The per-sample fast path and the block path agree, NaN gaps included."""
    data = np.array(rows)
    a, b = RangeTracker(3), RangeTracker(3)
    for r in data:
        a.update(r)
    b.update_many(data)
    np.testing.assert_array_equal(a.count, b.count)
    np.testing.assert_allclose(a.minimum, b.minimum, atol=1e-9)
    np.testing.assert_allclose(a.maximum, b.maximum, atol=1e-9)
    np.testing.assert_allclose(a.current, b.current, atol=1e-9)
