from __future__ import annotations

from pathlib import Path

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq
import pytest
from dataset_testutil import (
    HI,
    HOMING_A,
    HOMING_B,
    LO,
    RANGE_A,
    RANGE_B,
    A,
    all_values,
    cals,
    column,
    tree,
)
from hypothesis import given
from hypothesis import strategies as st

from robocal.core.lerobot import LegacyCalibration
from robocal.dataset import (
    SO_ARM_JOINTS,
    generate_dataset,
    recalibrate_dataset,
    recalibrate_values,
)
from robocal.dataset._convention import select_indices
from robocal.dataset.lerobot import (
    LegacyConvention,
    LeRobotConvention,
    motor_family_for_robot,
    preset_modes,
)
from robocal.errors import JointMismatchError, UsageError
from robocal.lerobot import MotorCalibration, unnormalize


def conv(homing, ranges, *, use_degrees=True, compat="lerobot", robot="so101_follower", drive=None):
    modes = preset_modes(robot, SO_ARM_JOINTS, use_degrees)
    return LeRobotConvention.from_calibrations(
        cals(homing, ranges, drive), modes, motor_family_for_robot(robot), compat
    )


def test_presets() -> None:
    assert preset_modes("so101_follower", ["shoulder_pan", "gripper"]) == {
        "shoulder_pan": "degrees",
        "gripper": "range_0_100",
    }
    assert preset_modes("so100_follower", ["elbow_flex"], use_degrees=False) == {
        "elbow_flex": "range_m100_100"
    }
    assert preset_modes("koch_follower", ["elbow_flex"]) == {"elbow_flex": "range_m100_100"}
    assert preset_modes("koch_follower", ["elbow_flex"], True) == {"elbow_flex": "degrees"}
    assert motor_family_for_robot("so_leader") == "feetech"
    assert motor_family_for_robot("koch_leader") == "dynamixel"
    with pytest.raises(UsageError, match=r"--robot 'ur5e': unknown robot type; known: so\*"):
        motor_family_for_robot("ur5e")


def test_golden_feetech_values() -> None:
    a, b = conv(HOMING_A, RANGE_A), conv(HOMING_B, RANGE_B)
    values = np.zeros((1, 6))
    values[0, 5] = 25.0  # gripper, range_0_100 on 1000..3000 → present 1500 → actual 1500
    new, mask = recalibrate_values(values, a, b)
    # shoulder_pan: present mid(900, 2950) = 1925 → actual 2025 → present_B 2175, mid_B 2150 → 25 ticks
    assert new[0, 0] == pytest.approx(25 * 360 / 4095, abs=1e-12)
    # gripper: actual 1500 → present_B 1000 on 0..2000 → 50 %
    assert new[0, 5] == pytest.approx(50.0, abs=1e-12)
    assert not mask.any()


def test_golden_dynamixel_and_wrap() -> None:
    modes = dict.fromkeys(["j"], "range_m100_100")
    a = LeRobotConvention.from_calibrations(
        {"j": MotorCalibration(1, 0, 100, 1000, 3000)}, modes, "dynamixel"
    )
    b = LeRobotConvention.from_calibrations(
        {"j": MotorCalibration(1, 0, -100, 1000, 3000)}, modes, "dynamixel"
    )
    # Dynamixel: actual = present − homing. Value 0 → present 2000 → actual 1900 → present_B 1800 → −20.
    new, mask = recalibrate_values(np.array([[0.0]]), a, b)
    assert new[0, 0] == pytest.approx(-20.0)
    # Feetech single-turn: present wraps into [0, 4096)
    fa = LeRobotConvention.from_calibrations({"j": MotorCalibration(1, 0, 0, 0, 4095)}, modes, "feetech")
    fb = LeRobotConvention.from_calibrations({"j": MotorCalibration(1, 0, -2500, 0, 4095)}, modes, "feetech")
    actual = fa.to_actual(np.array([[-2.3199023199023]]))  # present 2000
    assert actual[0, 0] == 2000
    new, mask = fb.from_actual(actual)
    assert new[0, 0] == pytest.approx(404 / 4095 * 200 - 100)
    assert not mask.any()


def test_out_of_range_is_counted_and_clamped() -> None:
    modes = {"j": "range_m100_100"}
    a = LeRobotConvention.from_calibrations({"j": MotorCalibration(1, 0, 0, 1000, 3000)}, modes, "feetech")
    b = LeRobotConvention.from_calibrations({"j": MotorCalibration(1, 0, 0, 1500, 2500)}, modes, "feetech")
    new, mask = recalibrate_values(np.array([[-100.0], [0.0], [100.0]]), a, b)
    np.testing.assert_allclose(new[:, 0], [-100.0, 0.0, 100.0])
    assert mask[:, 0].tolist() == [True, False, True]


def _ticks(values: np.ndarray, c: LeRobotConvention) -> np.ndarray:
    return unnormalize(values, c.calibrations, c.modes, compat=c.compat)


@pytest.mark.parametrize("use_degrees", [True, False])
def test_dataset_round_trip_lerobot_within_one_tick(tmp_path: Path, use_degrees: bool) -> None:
    a = conv(HOMING_A, RANGE_A, use_degrees=use_degrees)
    b = conv(HOMING_B, RANGE_B, use_degrees=use_degrees)
    src = tmp_path / "a"
    motion = {  # the same seed gives the same actual ticks: one motion, recorded with a given calibration
        "n_episodes": 3,
        "frames_per_episode": [60, 45, 70],
        "episodes_per_file": 2,
        "actual_lo": [1100, 1100, 1100, 1100, 200, 1100],
        "actual_hi": [2800, 2800, 2800, 2700, 3900, 2400],
    }
    generate_dataset(src, convention=a, **motion)
    rep = recalibrate_dataset(src, tmp_path / "b", a, b)
    assert rep.out_of_range["observation.state"] == dict.fromkeys(SO_ARM_JOINTS, 0)
    recalibrate_dataset(tmp_path / "b", tmp_path / "aa", b, a, workers=2)
    assert tree(tmp_path / "aa") == tree(src)
    # the same motion recorded by LeRobot with calibration B (same seed → same actual ticks)
    generate_dataset(tmp_path / "rec_b", convention=b, **motion)
    for key in ("observation.state", "action"):
        orig, back = all_values(src, key), all_values(tmp_path / "aa", key)
        assert np.abs(_ticks(back, a) - _ticks(orig, a)).max() <= 1  # LeRobot's truncating read-back
        # readings are whole ticks, recovered to the nearest tick: the round trip is bit-identical
        np.testing.assert_array_equal(back, orig)
        # and A → B gives exactly what LeRobot would have recorded with calibration B
        np.testing.assert_array_equal(all_values(tmp_path / "b", key), all_values(tmp_path / "rec_b", key))
    s, d = (
        pq.ParquetFile(src / "data/chunk-000/file-000.parquet"),
        pq.ParquetFile(tmp_path / "aa/data/chunk-000/file-000.parquet"),
    )
    assert d.schema_arrow == s.schema_arrow and d.schema_arrow.metadata == s.schema_arrow.metadata
    assert d.metadata.num_row_groups == 2


def test_dataset_round_trip_exact_is_bit_identical(tmp_path: Path) -> None:
    a = conv(HOMING_A, RANGE_A, compat="exact")
    b = conv(HOMING_B, RANGE_B, compat="exact", use_degrees=False)  # and change of modes on the way
    src = tmp_path / "a"
    generate_dataset(
        src,
        n_episodes=2,
        frames_per_episode=80,
        convention=a,
        actual_lo=[1100, 1100, 1100, 1100, 200, 1100],
        actual_hi=[2800, 2800, 2800, 2700, 3900, 2400],
    )
    recalibrate_dataset(src, tmp_path / "b", a, b)
    recalibrate_dataset(tmp_path / "b", tmp_path / "aa", b, a)
    for key in ("observation.state", "action"):
        np.testing.assert_array_equal(all_values(tmp_path / "aa", key), all_values(src, key))
    assert not np.array_equal(all_values(tmp_path / "b", "action"), all_values(src, "action"))


def test_off_grid_values_move_less_than_one_tick() -> None:
    a, b = conv(HOMING_A, RANGE_A), conv(HOMING_B, RANGE_B)
    rng = np.random.default_rng(3)
    values = np.column_stack([rng.uniform(-60, 60, (200, 5)), rng.uniform(5, 70, 200)])  # e.g. policy actions
    back, _ = recalibrate_values(recalibrate_values(values, a, b)[0], b, a)
    tick = np.array([360 / 4095] * 5 + [100 / 2000])
    assert np.all(np.abs(back - values) <= tick * 0.5 + 1e-9)
    assert np.abs(_ticks(back, a) - _ticks(values, a)).max() <= 1


@given(
    st.lists(st.integers(-600, 600), min_size=6, max_size=6),
    st.lists(st.integers(0, 1), min_size=6, max_size=6),
    st.lists(st.integers(1300, 2700), min_size=6, max_size=24),
)
def test_exact_round_trip_property(homing_b: list[int], drive_b: list[int], actual: list[int]) -> None:
    a = conv(HOMING_A, [(0, 4095)] * 6, compat="exact", use_degrees=False)
    b = conv(homing_b, [(0, 4095)] * 6, compat="exact", drive=drive_b)
    act = np.array(actual[: len(actual) // 6 * 6] or actual[:6] * 1, dtype=np.float64).reshape(-1, 6)
    va, _ = a.from_actual(act)
    va32 = va.astype(np.float32).astype(np.float64)
    vb, mask = recalibrate_values(va32, a, b)
    assert not mask.any()
    back, _ = recalibrate_values(vb.astype(np.float32).astype(np.float64), b, a)
    np.testing.assert_array_equal(back.astype(np.float32), va32.astype(np.float32))


def test_legacy_convention_matches_lerobot_legacy() -> None:
    cal = LegacyCalibration(
        ["shoulder_pan", "gripper"], [-2145, 0], [0, 0], [2085, 1983], [3169, 2793], ["DEGREE", "LINEAR"]
    )
    legacy = LegacyConvention(cal)
    raw = np.array([[2145.0, 1983.0], [3169.0, 2793.0], [2500.0, 2400.0]])
    values, mask = legacy.from_actual(raw)
    np.testing.assert_allclose(values[:, 0], [0.0, 1024 / 2048 * 180, 355 / 2048 * 180])
    np.testing.assert_allclose(values[:, 1], [0.0, 100.0, 417 / 810 * 100])
    assert not mask.any()
    np.testing.assert_array_equal(legacy.to_actual(values), raw)
    # beyond ±270° LeRobot raises; here the value is converted and counted
    far, mask = legacy.from_actual(np.array([[2145.0 + 3200, 1983.0]]))
    assert far[0, 0] == pytest.approx(3200 / 2048 * 180)
    assert mask.tolist() == [[True, False]]


def test_tick_lookup_path_equals_direct_map() -> None:
    a, b = conv(HOMING_A, RANGE_A), conv(HOMING_B, RANGE_B, use_degrees=False)
    rng = np.random.default_rng(7)
    actual = rng.integers(1000, 3200, size=(20000, 6)).astype(np.float64)  # some outside B's ranges
    values = a.from_actual(actual)[0].astype(np.float32).astype(np.float64)
    fast, fast_mask = recalibrate_values(values, a, b)  # > 8192 rows: one map per distinct tick
    slow, slow_mask = b.from_actual(a.to_actual(values))
    np.testing.assert_array_equal(fast, slow)
    np.testing.assert_array_equal(fast_mask, slow_mask)
    assert 0 < int(fast_mask.sum()) < fast_mask.size


def test_dynamixel_drive_mode_flip_refused(tmp_path: Path) -> None:
    modes = preset_modes("koch_follower", SO_ARM_JOINTS)
    a = LeRobotConvention.from_calibrations(cals(HOMING_A, RANGE_A), modes, "dynamixel")
    b = LeRobotConvention.from_calibrations(cals(HOMING_B, RANGE_B, [0, 0, 1, 0, 0, 0]), modes, "dynamixel")
    src = tmp_path / "src"
    generate_dataset(src, n_episodes=1, frames_per_episode=10, convention=a, robot_type="koch_follower")
    with pytest.raises(
        UsageError, match="Dynamixel drive_mode differs between the calibrations for elbow_flex"
    ):
        recalibrate_dataset(src, tmp_path / "dst", a, b)
    assert not (tmp_path / "dst").exists()


def test_off_grid_large_batch_uses_tick_lookup_and_matches() -> None:
    a, b = conv(HOMING_A, RANGE_A), conv(HOMING_B, RANGE_B)
    rng = np.random.default_rng(11)
    values = np.column_stack([rng.uniform(-60, 60, (20000, 5)), rng.uniform(5, 70, 20000)])  # all distinct
    fast, fast_mask = recalibrate_values(values, a, b)
    slow, slow_mask = b.from_actual(a.to_actual(values))
    np.testing.assert_array_equal(fast, slow)
    np.testing.assert_array_equal(fast_mask, slow_mask)


def test_legacy_dataset_to_current_and_back(tmp_path: Path) -> None:
    legacy = LegacyConvention(
        LegacyCalibration(
            SO_ARM_JOINTS,
            [-2048, 1024, -2000, -2100, -2048, 0],
            [0, 1, 0, 0, 0, 0],
            [0] * 5 + [1100],
            [1024] * 5 + [2500],
            ["DEGREE"] * 5 + ["LINEAR"],
        )
    )
    current = conv(HOMING_A, RANGE_A)
    src = tmp_path / "legacy"
    generate_dataset(src, n_episodes=2, frames_per_episode=50, convention=legacy, actual_lo=LO, actual_hi=HI)
    rep = recalibrate_dataset(src, tmp_path / "current", legacy, current)
    assert rep.out_of_range["action"] == dict.fromkeys(SO_ARM_JOINTS, 0)
    recalibrate_dataset(tmp_path / "current", tmp_path / "back", current, legacy)
    for key in ("observation.state", "action"):
        np.testing.assert_array_equal(all_values(tmp_path / "back", key), all_values(src, key))
    # legacy degrees of shoulder_pan: (raw − 2048)/2048·180 with raw = actual; current: degrees about mid 1925
    leg = all_values(src, "observation.state")[:, 0]
    cur = all_values(tmp_path / "current", "observation.state")[:, 0]
    actual = np.round(leg / 180 * 2048 + 2048)
    np.testing.assert_allclose(cur, (actual - 100 - 1925) * 360 / 4095, atol=1e-4)


def test_legacy_degree_motor_with_equal_start_and_end() -> None:
    # start_pos/end_pos only matter for LINEAR motors
    cal = LegacyCalibration(["j"], [-2048], [0], [0], [0], ["DEGREE"])
    values, mask = LegacyConvention(cal).from_actual(np.array([[3072.0]]))
    assert values.tolist() == [[90.0]] and not mask.any()


def _degrees_feetech(homing: int) -> LeRobotConvention:
    cal = {"j": MotorCalibration(1, 0, homing, 0, 4095)}
    return LeRobotConvention.from_calibrations(cal, {"j": "degrees"}, "feetech")


@pytest.mark.parametrize("rows", [3, 20000])  # per-frame path and the distinct-value/tick look-up paths
def test_feetech_value_from_no_single_turn_is_counted(rows: int) -> None:
    a, b = _degrees_feetech(100), _degrees_feetech(-50)
    values = np.zeros((rows, 1))
    values[1, 0] = 1e6  # present ≈ 11.4 M ticks: no single-turn reading gives that
    values[2, 0] = -200.0  # present 2047 − 2275 < 0: below the turn
    new, mask = recalibrate_values(values, a, b)
    assert mask[:, 0].tolist() == [False, True, True] + [False] * (rows - 3)
    assert np.isfinite(new).all()
    # inside the turn and wrapped once by the new homing: not counted (179° is present 4084 < 4096,
    # actual 4184, new present 4234 → 138)
    new, mask = recalibrate_values(np.array([[179.0]]), a, b)
    assert not mask.any()
    assert new[0, 0] == pytest.approx((138 - 2047.5) * 360 / 4095)


def test_feetech_unreachable_values_are_reported_per_joint(tmp_path: Path) -> None:
    conv = LeRobotConvention.from_calibrations(
        {n: MotorCalibration(i + 1, 0, 0, 0, 4095) for i, n in enumerate(SO_ARM_JOINTS)},
        preset_modes("so101_follower", SO_ARM_JOINTS),
        "feetech",
    )
    src = tmp_path / "src"
    generate_dataset(src, n_episodes=2, frames_per_episode=10, convention=conv, actual_lo=LO, actual_hi=HI)
    path = src / "data/chunk-000/file-000.parquet"
    table = pq.read_table(path)
    vals = column(path, "action").astype(np.float32)
    vals[3, 1] = 1e6  # shoulder_lift, degrees mode
    arr = pa.FixedSizeListArray.from_arrays(pa.array(vals.reshape(-1)), 6)
    table = table.set_column(table.schema.get_field_index("action"), table.schema.field("action"), arr)
    pq.write_table(table, path, row_group_size=10)
    rep = recalibrate_dataset(src, tmp_path / "dst", conv, conv)  # same calibration: nothing else moves
    assert rep.out_of_range["action"] == {n: int(n == "shoulder_lift") for n in SO_ARM_JOINTS}
    assert rep.out_of_range["observation.state"] == dict.fromkeys(SO_ARM_JOINTS, 0)
    assert rep.warnings == [
        "action: values outside the new calibrated range (clamped where the mode clamps): shoulder_lift 1"
    ]


def test_far_actual_position_is_counted_on_the_feetech_side() -> None:
    b = _degrees_feetech(0)
    _, mask = b.from_actual(np.array([[2000.0], [2000.0 + 4096], [2000.0 + 3 * 4096], [-5000.0]]))
    # one wrap is what two calibrations produce; more than one turn away is counted
    assert mask[:, 0].tolist() == [False, False, True, True]


def test_select_reorders_and_names_what_is_missing_in_each_convention() -> None:
    assert select_indices(["c", "a"], ["a", "b", "c", "a"], "x", "joint") == [2, 0]  # first occurrence
    with pytest.raises(JointMismatchError, match=r"^x: no joint named d, e$"):
        select_indices(["a", "d", "e"], ["a", "b"], "x", "joint")
    sub = A.select(["elbow_flex", "shoulder_pan"])
    assert sub.joint_names == ("elbow_flex", "shoulder_pan")
    assert sub.calibration.homing_offset.tolist() == [2100, 2047]
    with pytest.raises(JointMismatchError, match=r"^joint map: no joint named knee$"):
        A.select(["shoulder_pan", "knee"])
    cur = conv(HOMING_A, RANGE_A).select(["gripper", "shoulder_pan"])
    assert cur.joint_names == ("gripper", "shoulder_pan")
    assert cur.modes == ("range_0_100", "degrees")
    with pytest.raises(JointMismatchError, match=r"^LeRobot calibration: no motor named knee$"):
        conv(HOMING_A, RANGE_A).select(["knee"])
    legacy = LegacyConvention(
        LegacyCalibration(
            ["shoulder_pan", "gripper"], [-2145, 0], [0, 0], [2085, 1983], [3169, 2793], ["DEGREE", "LINEAR"]
        )
    )
    assert legacy.select(["gripper"]).calibration.homing_offset.tolist() == [0]
    with pytest.raises(JointMismatchError, match=r"^legacy calibration: no motor named knee$"):
        legacy.select(["knee", "gripper"])
