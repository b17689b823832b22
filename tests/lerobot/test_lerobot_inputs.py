"""``normalize`` / ``unnormalize`` refuse what is not a number, and ``compat`` changes rounding only (issue #9)."""

from __future__ import annotations

import datetime

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from robocal.errors import InvalidCalibrationError, ShapeMismatchError
from robocal.lerobot import MotorCalibration, NormMode, normalize, unnormalize

CAL = MotorCalibration(id=1, drive_mode=0, homing_offset=0, range_min=1000, range_max=3000)
CAL_DM = MotorCalibration(id=2, drive_mode=1, homing_offset=0, range_min=1000, range_max=3000)


# ------------------------------------------------------------------------------------ refused inputs
@pytest.mark.parametrize(
    ("raw", "message"),
    [
        (np.array(["2024-01-01T00:00:01"], dtype="datetime64[s]"), "raw contains datetime64 values"),
        (np.array([1500 + 2j]), "raw contains complex numbers"),
        (np.array([1500 + 0j]), "raw contains complex numbers"),  # even with no imaginary part
        ([1500j], "raw contains complex numbers"),
        (np.array([10], dtype="timedelta64[s]"), "raw contains timedelta64 values"),
        ("1500", "raw contains strings"),
        (["1500", "2000"], "raw contains strings"),
        (np.array(["1500"]), "raw contains strings"),
        ([b"1500"], "raw contains byte strings"),
        ([True, False], "raw contains booleans"),
        (None, "raw has a missing value (None); expected numbers"),
        ([1500, None], "raw has a missing value (None) (element 1); expected numbers"),
        ([1500, "2000"], "raw contains strings"),  # numpy makes this a string array
        (np.array([1500, "x"], dtype=object), "raw contains str 'x'"),
        ([1500, datetime.date(2024, 1, 1)], "raw contains date"),
    ],
)
def test_normalize_refuses_what_is_not_a_real_number(raw: object, message: str) -> None:
    cal = [CAL, CAL_DM] if isinstance(raw, list) and len(raw) == 2 else CAL
    with pytest.raises(InvalidCalibrationError) as info:
        normalize(raw, cal, "degrees")  # type: ignore[arg-type]
    assert str(info.value).startswith(message)
    assert "NaN" not in str(info.value)


def test_unnormalize_refuses_the_same() -> None:
    with pytest.raises(InvalidCalibrationError, match="values contains strings"):
        unnormalize("12.5", CAL, "degrees")  # type: ignore[arg-type]
    with pytest.raises(InvalidCalibrationError, match=r"values has a missing value \(None\)"):
        unnormalize([None], [CAL], "degrees")  # type: ignore[list-item]
    with pytest.raises(InvalidCalibrationError, match="values contains complex numbers"):
        unnormalize(np.array([1.0 + 1j]), [CAL], "degrees")


def test_nan_is_still_reported_as_nan() -> None:
    with pytest.raises(InvalidCalibrationError, match="raw contains NaN or inf"):
        normalize([float("nan")], [CAL], "degrees")


@pytest.mark.parametrize("dm", [7, 2, -1])
def test_in_memory_drive_mode_other_than_0_or_1_is_refused(dm: int) -> None:
    cal = MotorCalibration(id=1, drive_mode=dm, homing_offset=0, range_min=1000, range_max=3000)
    for mode in ("degrees", "range_m100_100", "range_0_100"):
        with pytest.raises(InvalidCalibrationError, match=f"motor 0: drive_mode is {dm}; expected 0 or 1"):
            normalize(1500, cal, mode)
        with pytest.raises(InvalidCalibrationError, match=f"drive_mode is {dm}"):
            unnormalize(10.0, [CAL, cal], [mode, mode])


def test_integer_and_float_inputs_still_work() -> None:
    assert normalize(np.array([2000], dtype=np.uint16), [CAL], "degrees").tolist() == [0.0]
    assert normalize(np.int32(3000), CAL, "range_0_100") == 100.0
    assert normalize(np.array([1500], dtype=object), [CAL], "range_0_100").tolist() == [25.0]
    assert normalize(np.float32(1500.0), CAL, "range_0_100") == 25.0


# ------------------------------------------------------------------------------ modes by motor name
def test_modes_by_motor_name_are_per_motor_modes() -> None:
    cals = {"gripper": CAL, "elbow_flex": CAL_DM}
    raw = [1500, 1500]
    by_name = normalize(raw, cals, {"elbow_flex": "range_m100_100", "gripper": NormMode.RANGE_0_100})
    assert by_name.tolist() == [25.0, 50.0]  # gripper 25 %, inverted elbow +50 (not the key names as modes)
    assert by_name.tolist() == normalize(raw, cals, ["range_0_100", "range_m100_100"]).tolist()
    assert unnormalize(
        [25.0, 50.0], cals, {"gripper": "range_0_100", "elbow_flex": "range_m100_100"}
    ).tolist() == [
        1500,
        1500,
    ]


@pytest.mark.parametrize(
    ("cals", "modes", "error", "message"),
    [
        (
            {"a": CAL, "b": CAL},
            {"a": "degrees"},
            ShapeMismatchError,
            "modes by motor name: no mode for motor(s) b",
        ),
        (
            {"a": CAL},
            {"a": "degrees", "z": "degrees"},
            ShapeMismatchError,
            "modes by motor name: mode(s) for unknown motor(s) z",
        ),
        ({"a": CAL}, {"a": "deg"}, InvalidCalibrationError, "motor 'a': norm mode 'deg'"),
        (
            [CAL],
            {"a": "degrees"},
            InvalidCalibrationError,
            "modes given by motor name need the calibration as",
        ),
        (CAL, {"a": "degrees"}, InvalidCalibrationError, "modes given by motor name need the calibration as"),
    ],
)
def test_modes_by_name_mismatch_is_refused_clearly(
    cals: object, modes: object, error: type, message: str
) -> None:
    with pytest.raises(error) as info:
        normalize([1500], cals, modes)  # type: ignore[arg-type]
    assert str(info.value).startswith(message)


# ---------------------------------------------------------------------------- compat changes rounding only
@pytest.mark.slow
@given(
    lo=st.integers(-2048, 4000),
    width=st.integers(1, 4095),
    dm=st.integers(0, 1),
    dm_hw=st.booleans(),
    mode=st.sampled_from(list(NormMode)),
    convention=st.sampled_from(["lerobot", "physical"]),
    data=st.data(),
)
def test_exact_is_lerobot_up_to_its_truncation(
    lo: int, width: int, dm: int, dm_hw: bool, mode: NormMode, convention: str, data: st.DataObject
) -> None:
    cal = MotorCalibration(7, dm, 0, lo, lo + width)
    raws = np.array(data.draw(st.lists(st.integers(lo - 100, lo + width + 100), min_size=1, max_size=30)))
    kw = {"apply_drive_mode": dm_hw, "convention": convention}
    a = normalize(raws, cal, mode, compat="lerobot", **kw)  # type: ignore[arg-type]
    b = normalize(raws, cal, mode, compat="exact", **kw)  # type: ignore[arg-type]
    assert a.tobytes() == b.tobytes()  # normalising does not round: bit-identical
    values = np.array(data.draw(st.lists(st.floats(-300, 300), min_size=1, max_size=30)))
    t = unnormalize(values, cal, mode, compat="lerobot", **kw)  # type: ignore[arg-type]
    r = unnormalize(values, cal, mode, compat="exact", **kw)  # type: ignore[arg-type]
    assert np.all(np.abs(r - t) <= 1)  # the same value, truncated vs rounded: never more than one tick
    # the same sign: rounding and truncation agree where the value is whole
    whole = unnormalize(normalize(raws, cal, mode, **kw), cal, mode, compat="exact", **kw)  # type: ignore[arg-type]
    if mode != NormMode.DEGREES:
        raws = np.clip(raws, lo, lo + width)
    assert whole.tolist() == raws.tolist()


def test_switching_lerobot_to_exact_does_not_flip_a_drive_mode_1_motor() -> None:
    """The issue's case: a Feetech drive_mode-1 motor in DEGREES flipped sign between lerobot and exact."""
    lerobot = float(normalize(3000, CAL_DM, "degrees", compat="lerobot"))
    exact = float(normalize(3000, CAL_DM, "degrees", compat="exact"))
    assert lerobot == exact == 1000 * 360 / 4095
    assert unnormalize(lerobot, CAL_DM, "degrees", compat="exact") == 3000
    assert unnormalize(10.0, CAL_DM, "degrees", compat="lerobot") == 2113  # int(10·4095/360 + 2000) = 2113
    assert unnormalize(10.0, CAL_DM, "degrees", compat="exact") == 2114  # rounded: 2113.75 → 2114


def test_unknown_convention_is_refused() -> None:
    with pytest.raises(InvalidCalibrationError, match="convention 'si': expected 'lerobot' or 'physical'"):
        normalize(1500, CAL, "degrees", convention="si")  # type: ignore[arg-type]


# ------------------------------------------------------------- the physical convention, named explicitly
def test_dataset_convention_exact_keeps_lerobot_signs_physical_flips_drive_mode_1() -> None:
    from robocal.dataset.lerobot import LeRobotConvention

    cals = {"elbow_flex": CAL_DM, "wrist_flex": CAL}
    modes = {"elbow_flex": "degrees", "wrist_flex": "degrees"}
    actual = np.array([[3000.0, 3000.0]])
    values = {
        (compat, convention): LeRobotConvention.from_calibrations(
            cals, modes, "feetech", compat, convention
        ).from_actual(actual)[0]
        for compat in ("lerobot", "exact")
        for convention in ("lerobot", "physical")
    }
    lerobot = 1000 * 360 / 4095
    assert values[("lerobot", "lerobot")].tolist() == [[lerobot, lerobot]]
    assert values[("exact", "lerobot")].tolist() == [[lerobot, lerobot]]  # no sign flip, same scale
    physical = 1000 * 360 / 4096
    assert values[("exact", "physical")].tolist() == [[-physical, physical]]
    assert values[("lerobot", "physical")].tolist() == [[-physical, physical]]
    for (compat, convention), v in values.items():  # and each reads back to the same actual ticks
        conv = LeRobotConvention.from_calibrations(cals, modes, "feetech", compat, convention)
        assert conv.to_actual(v.astype(np.float32).astype(np.float64)).tolist() == actual.tolist()


def test_export_joint_map_compat_does_not_change_it_physical_does() -> None:
    from robocal.workflows.lerobot import export_joint_map, robot_spec

    spec = robot_spec("so101_follower")
    cals = {
        m.name: MotorCalibration(m.motor_id, int(m.name == "elbow_flex"), 0, 1000, 3000) for m in spec.motors
    }
    a, _ = export_joint_map(spec, cals, compat="lerobot")
    b, _ = export_joint_map(spec, cals, compat="exact")
    c, _ = export_joint_map(spec, cals, convention="physical")
    for field in ("direction", "homing_offset", "scale"):
        assert getattr(a, field).tobytes() == getattr(b, field).tobytes()
    elbow = a.joint_names.index("elbow_flex")
    assert float(a.direction[elbow]) == 1.0 and float(c.direction[elbow]) == -1.0
    assert float(a.scale[elbow]) == pytest.approx(2 * np.pi / 4095, rel=1e-15)
    assert float(c.scale[elbow]) == pytest.approx(2 * np.pi / 4096, rel=1e-15)
