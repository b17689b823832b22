from __future__ import annotations

import math

import numpy as np
import pytest
from counting import CountingName
from hypothesis import given
from hypothesis import strategies as st
from hypothesis.extra import numpy as hnp

from robocal.core import JointMap, RobotCalibration
from robocal.errors import CalibError, InvalidCalibrationError, JointMismatchError, ShapeMismatchError

finite = st.floats(-50.0, 50.0, allow_nan=False, allow_infinity=False)
scales = st.sampled_from([1.0, 2 * math.pi / 4096, math.pi / 2048, 0.5, 9.0])


@st.composite
def calibrations(draw: st.DrawFn) -> RobotCalibration:
    n = draw(st.integers(1, 16))
    d = draw(st.lists(st.sampled_from([-1, 1]), min_size=n, max_size=n))
    h = draw(st.lists(finite, min_size=n, max_size=n))
    s = draw(st.lists(scales, min_size=n, max_size=n))
    return RobotCalibration([f"j{i}" for i in range(n)], d, h, s)


def test_seed_formula_worked_example() -> None:
    # left_elbow_pitch: direction -1, true homing offset 1.0 rad; raw 1.0 is the upper stop (q = 0).
    cal = RobotCalibration(["left_elbow_pitch"], [-1], [1.0])
    assert cal.to_joint(np.array([1.0]))[0] == 0.0
    assert cal.to_joint(np.array([3.356]))[0] == pytest.approx(-2.356, abs=1e-15)
    assert cal.to_raw(np.array([-2.356]))[0] == pytest.approx(3.356, abs=1e-15)


def test_scalar_tick_and_recording_shapes() -> None:
    cal = RobotCalibration(["a", "b", "c"], [1, -1, 1], [0.5, -0.25, 2.0], [1.0, 1.0, 0.5])
    tick = np.array([1.0, 1.0, 1.0])
    np.testing.assert_array_equal(cal.to_joint(tick), [0.5, -1.25, -0.5])
    rec = np.tile(tick, (5, 1))
    assert cal.to_joint(rec).shape == (5, 3)
    np.testing.assert_array_equal(cal.to_joint(rec)[3], [0.5, -1.25, -0.5])
    one = RobotCalibration(["a"], [-1], [0.5])
    assert float(one.to_joint(1.5)) == -1.0
    # velocity and effort: direction*scale only, no offset
    np.testing.assert_array_equal(cal.velocity_to_joint(tick), [1.0, -1.0, 0.5])
    np.testing.assert_array_equal(cal.effort_to_joint(tick), [1.0, -1.0, 0.5])
    np.testing.assert_array_equal(cal.velocity_to_raw([1.0, -1.0, 0.5]), tick)


@given(calibrations(), st.data())
def test_to_raw_inverts_to_joint(cal: RobotCalibration, data: st.DataObject) -> None:
    t = data.draw(st.integers(1, 8))
    raw = data.draw(hnp.arrays(np.float64, (t, cal.n_joints), elements=finite))
    back = cal.to_raw(cal.to_joint(raw))
    np.testing.assert_allclose(back, raw, rtol=0, atol=1e-12)
    v = cal.velocity_to_raw(cal.velocity_to_joint(raw))
    np.testing.assert_allclose(v, raw, rtol=0, atol=1e-12)
    e = cal.effort_to_raw(cal.effort_to_joint(raw))
    np.testing.assert_allclose(e, raw, rtol=0, atol=1e-12)


@given(calibrations())
def test_joint_map_matches_robot_calibration(cal: RobotCalibration) -> None:
    raw = np.linspace(-3, 3, cal.n_joints)
    per_joint = [cal.joint_map(n).to_joint(raw[i]) for i, n in enumerate(cal.joint_names)]
    np.testing.assert_allclose(cal.to_joint(raw), per_joint, rtol=0, atol=1e-12)
    assert RobotCalibration.from_joint_maps(cal.joint_maps()).is_close(cal, 0.0)


def test_select_reorders_and_rejects_unknown() -> None:
    cal = RobotCalibration(["a", "b"], [1, -1], [0.1, 0.2])
    sub = cal.select(["b", "a"])
    assert sub.joint_names == ("b", "a")
    np.testing.assert_array_equal(sub.homing_offset, [0.2, 0.1])
    with pytest.raises(JointMismatchError, match="joints not in the calibration: z"):
        cal.select(["a", "z"])
    with pytest.raises(JointMismatchError, match="unknown joint 'q'"):
        cal.index("q")


@pytest.mark.parametrize(
    ("kwargs", "error", "message"),
    [
        ({"direction": [0, 1]}, InvalidCalibrationError, "joint 'a': direction 0 is invalid"),
        ({"direction": [2, 1]}, InvalidCalibrationError, "joint 'a': direction 2 is invalid"),
        ({"homing_offset": [math.nan, 0.0]}, InvalidCalibrationError, "joint 'a': homing_offset is nan"),
        ({"homing_offset": [0.0, math.inf]}, InvalidCalibrationError, "joint 'b': homing_offset is inf"),
        ({"scale": [0.0, 1.0]}, InvalidCalibrationError, "joint 'a': scale 0.0 must be finite and > 0"),
        (
            {"homing_offset": [0.0, 1.0, 2.0]},
            ShapeMismatchError,
            r"homing_offset has shape \(3,\); expected \(2,\)",
        ),
        ({"names": ["a", "a"]}, JointMismatchError, "duplicate joint names: a"),
    ],
)
def test_invalid_calibrations_are_rejected(
    kwargs: dict[str, object], error: type[Exception], message: str
) -> None:
    args: dict[str, object] = {
        "names": ["a", "b"],
        "direction": [1, 1],
        "homing_offset": [0.0, 0.0],
        "scale": 1.0,
    }
    args.update(kwargs)
    with pytest.raises(error, match=message) as info:
        RobotCalibration(args["names"], args["direction"], args["homing_offset"], args["scale"])  # type: ignore[arg-type]
    assert isinstance(info.value, CalibError)


def test_shape_mismatch_on_mapping() -> None:
    cal = RobotCalibration(["a", "b"], [1, 1], [0.0, 0.0])
    with pytest.raises(ShapeMismatchError, match=r"shape \(3,\); the last axis must have 2 joints"):
        cal.to_joint(np.zeros(3))
    with pytest.raises(ShapeMismatchError, match="scalar"):
        cal.to_joint(1.0)


def test_joint_map_validation() -> None:
    assert JointMap(-1, 0.5).to_joint(1.5) == -1.0
    with pytest.raises(InvalidCalibrationError, match="direction"):
        JointMap(0, 0.0)
    with pytest.raises(InvalidCalibrationError, match="homing_offset is nan"):
        JointMap(1, math.nan)
    with pytest.raises(InvalidCalibrationError, match="direction True"):
        JointMap(True, 0.0)  # type: ignore[arg-type]


def test_arrays_are_read_only() -> None:
    cal = RobotCalibration(["a"], [1], [0.5])
    with pytest.raises(ValueError):
        cal.homing_offset[0] = 1.0


def test_unwrap_to_limits_picks_branch_inside_limits() -> None:
    # Elbow with direction -1, limits [-2.356, 0], homing offset 3.0 rad: raw spans [3.0, 5.356].
    # After power-on in [-pi, pi) the raw 5.0 reads 5.0 - 2pi = -1.283: unwrap must restore 5.0.
    cal = RobotCalibration(["elbow"], [-1], [3.0])
    raw = np.array([5.0 - 2 * math.pi])
    fixed = cal.unwrap_to_limits(raw, [-2.356], [0.0])
    assert fixed[0] == pytest.approx(5.0, abs=1e-12)
    q = cal.to_joint(fixed)[0]
    assert -2.356 <= q <= 0.0


@given(calibrations(), st.data())
def test_unwrap_to_limits_recovers_any_turn(cal: RobotCalibration, data: st.DataObject) -> None:
    n = cal.n_joints
    cal = RobotCalibration(cal.joint_names, cal.direction, cal.homing_offset, 1.0)
    lo = np.array(data.draw(st.lists(st.floats(-3.0, 0.0), min_size=n, max_size=n)))
    width = np.array(data.draw(st.lists(st.floats(0.1, 6.0), min_size=n, max_size=n)))
    frac = np.array(data.draw(st.lists(st.floats(0.0, 1.0), min_size=n, max_size=n)))
    turns = np.array(data.draw(st.lists(st.integers(-3, 3), min_size=n, max_size=n)))
    q_true = lo + frac * width
    raw_true = cal.to_raw(q_true)
    fixed = cal.unwrap_to_limits(raw_true + turns * 2 * math.pi, lo, lo + width)
    np.testing.assert_allclose(fixed, raw_true, atol=1e-9)


def test_blocked_batch_path_is_bit_identical() -> None:
    rng = np.random.default_rng(3)
    cal = RobotCalibration(
        [f"j{i}" for i in range(14)],
        rng.choice([-1, 1], 14),
        rng.uniform(-3, 3, 14),
        rng.choice([1.0, 0.5], 14),
    )
    raw = rng.uniform(-5, 5, (100_003, 14))
    expected = cal._gain * (raw - cal.homing_offset)  # type: ignore[attr-defined]
    out = np.empty_like(raw)
    assert cal.to_joint(raw, out=out) is out
    np.testing.assert_array_equal(out, expected)
    np.testing.assert_array_equal(cal.to_joint(raw), expected)
    np.testing.assert_array_equal(cal.to_joint(raw[:, ::1].T.copy().T), expected)  # non-contiguous input
    with pytest.raises(ShapeMismatchError, match="out has shape"):
        cal.to_joint(raw, out=np.empty((3, 14)))


def test_unwrap_to_limits_refuses_inverted_limits() -> None:
    cal = RobotCalibration(["a", "b"], [1, 1], [0.0, 0.0])
    with pytest.raises(InvalidCalibrationError, match="lower limit above upper limit for b"):
        cal.unwrap_to_limits([0.0, 0.0], [-1.0, 1.0], [1.0, -1.0])


# ------------------------------------------------------------------------------ fused per-tick state map
zero_signs = st.sampled_from([0.0, -0.0])


@given(calibrations(), st.data())
def test_state_map_is_bit_identical_to_the_separate_maps(cal: RobotCalibration, data: st.DataObject) -> None:
    lead = data.draw(st.sampled_from([(), (2,), (2, 3)]))
    elems = st.one_of(finite, zero_signs, st.just(math.nan))
    raw = data.draw(hnp.arrays(np.float64, (*lead, 3, cal.n_joints), elements=elems))
    joint = cal.state_to_joint(raw)
    assert joint.shape == raw.shape
    for row, fn in enumerate((cal.to_joint, cal.velocity_to_joint, cal.effort_to_joint)):
        want = fn(raw[..., row, :])
        np.testing.assert_array_equal(joint[..., row, :], want)
        assert np.array_equal(np.signbit(joint[..., row, :]), np.signbit(want))  # -0.0 stays -0.0
    back = cal.state_to_raw(joint)
    for row, fn in enumerate((cal.to_raw, cal.velocity_to_raw, cal.effort_to_raw)):
        want = fn(joint[..., row, :])
        np.testing.assert_array_equal(back[..., row, :], want)
        assert np.array_equal(np.signbit(back[..., row, :]), np.signbit(want))
    finite_mask = np.isfinite(raw)
    np.testing.assert_allclose(back[finite_mask], raw[finite_mask], rtol=0, atol=1e-12)  # apply∘invert = id


def test_state_map_out_and_shape_errors() -> None:
    cal = RobotCalibration(["a", "b"], [1, -1], [0.5, 0.25], [1.0, 0.5])
    raw = np.array([[1.5, 0.25], [2.0, 2.0], [4.0, -4.0]])
    out = np.empty((3, 2))
    res = cal.state_to_joint(raw, out=out)
    assert res is out
    np.testing.assert_array_equal(out, [[1.0, 0.0], [2.0, -1.0], [4.0, 2.0]])
    np.testing.assert_array_equal(cal.state_to_joint(raw.tolist()), out)  # lists are accepted
    np.testing.assert_array_equal(cal.state_to_raw(out, out=np.empty((3, 2))), raw)
    assert raw.tolist() == [[1.5, 0.25], [2.0, 2.0], [4.0, -4.0]]  # input untouched
    with pytest.raises(ShapeMismatchError, match=r"expected \(3, 2\) rows position, velocity, effort"):
        cal.state_to_joint(np.zeros((2, 2)))
    with pytest.raises(ShapeMismatchError, match="last axis must have 2 joints"):
        cal.state_to_joint(np.zeros((3, 3)))
    with pytest.raises(ShapeMismatchError, match=r"out has shape \(2, 2\)"):
        cal.state_to_joint(raw, out=np.empty((2, 2)))
    with pytest.raises(ShapeMismatchError, match="out has list"):
        cal.state_to_raw(raw, out=[0.0] * 6)  # type: ignore[arg-type]


# --------------------------------------------------------------------------- linear in the joint count
def test_joint_lookups_are_linear_in_the_joint_count() -> None:
    n = 3000
    names = [CountingName(f"joint_{i}") for i in range(n)]
    CountingName.comparisons = 0
    cal = RobotCalibration(names, 1.0, np.arange(n, dtype=float))
    order = [CountingName(f"joint_{i}") for i in reversed(range(n))]  # equal names, other objects
    sel = cal.select(order)
    assert all(name in cal for name in order)
    assert [cal.index(name) for name in order[:3]] == [n - 1, n - 2, n - 3]
    assert sel.homing_offset[0] == n - 1
    assert CountingName.comparisons < 10 * n  # a quadratic search makes ~4.5 million here
    with pytest.raises(JointMismatchError, match="duplicate joint names: a, b"):
        RobotCalibration(["b", "a", "b", "c", "a"], 1.0, 0.0)


def test_calibration_pickles_with_its_lookup_table() -> None:
    import pickle

    cal = RobotCalibration(["a", "b"], [1, -1], [0.5, 0.25])
    back = pickle.loads(pickle.dumps(cal))
    assert back.index("b") == 1 and "a" in back and back.is_close(cal)
