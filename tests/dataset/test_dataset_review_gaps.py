"""Regression tests for the second review of the dataset area (each failed before its fix).

* LeKiwi-style features that mix joint positions with other entries, calibrations with extra motors;
* Feetech values that cannot come from one encoder turn are counted, not silently wrapped;
* data files without ``episode_index`` still get their dataset statistics recomputed (with a warning).
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq
import pytest
from dataset_testutil import HI, HOMING_A, HOMING_B, LO, RANGE_A, RANGE_B, all_values, column

from robocal.cli.main import main
from robocal.dataset import (
    SO_ARM_JOINTS,
    generate_dataset,
    inspect_dataset,
    recalibrate_dataset,
    recalibrate_table,
    recalibrate_values,
)
from robocal.dataset.lerobot import LeRobotConvention, preset_modes
from robocal.errors import FileFormatError, JointMismatchError
from robocal.lerobot import MotorCalibration, write_calibration

ARM = tuple(f"arm_{j}" for j in SO_ARM_JOINTS)
WHEELS = ("base_left_wheel", "base_back_wheel", "base_right_wheel")
VELOCITIES = ("x.vel", "y.vel", "theta.vel")
FEATURES = ("observation.state", "action")


def lekiwi_cals(homing: list[int], ranges: list[tuple[int, int]]) -> dict[str, MotorCalibration]:
    """A LeKiwi calibration: the six arm motors and three base wheels (not in the features)."""
    out = {n: MotorCalibration(i + 1, 0, homing[i], ranges[i][0], ranges[i][1]) for i, n in enumerate(ARM)}
    for k, n in enumerate(WHEELS):
        out[n] = MotorCalibration(7 + k, 0, 0, 0, 4095)
    return out


def lekiwi_conv(homing: list[int], ranges: list[tuple[int, int]]) -> LeRobotConvention:
    cals = lekiwi_cals(homing, ranges)
    modes = preset_modes("lekiwi", list(cals))
    return LeRobotConvention.from_calibrations(cals, modes, "feetech")


def _velocity_bits(rng: np.random.Generator, n: int) -> np.ndarray:
    """float32 velocities with awkward bit patterns (−0.0, a subnormal, tiny and huge values)."""
    v = rng.normal(0.0, 0.3, size=(n, len(VELOCITIES))).astype(np.float32)
    specials = np.array([-0.0, 1e-40, 3.4e38, -1.17e-38], dtype=np.float32)
    v.flat[: specials.size] = specials
    return v


def add_velocities(root: Path, seed: int = 7) -> None:
    """Append ``x.vel``, ``y.vel``, ``theta.vel`` to both vector features (data, info, HF metadata, stats)."""
    rng = np.random.default_rng(seed)
    d = len(ARM) + len(VELOCITIES)
    for path in sorted(root.glob("data/chunk-*/file-*.parquet")):
        pf = pq.ParquetFile(path)
        hf = json.loads(pf.schema_arrow.metadata[b"huggingface"])
        for key in FEATURES:
            hf["info"]["features"][key]["length"] = d
        tables = []
        for g in range(pf.metadata.num_row_groups):
            t = pf.read_row_group(g)
            for key in FEATURES:
                arm = column_of(t, key)
                vals = np.concatenate([arm, _velocity_bits(rng, t.num_rows)], axis=1)
                i = t.schema.get_field_index(key)
                arr = pa.FixedSizeListArray.from_arrays(pa.array(vals.reshape(-1), pa.float32()), d)
                t = t.set_column(i, pa.field(key, arr.type), arr)
            tables.append(t)
        schema = tables[0].schema.with_metadata({b"huggingface": json.dumps(hf).encode()})
        with pq.ParquetWriter(path, schema) as writer:
            for t in tables:
                writer.write_table(t.cast(schema), row_group_size=t.num_rows)
    info_path = root / "meta/info.json"
    info = json.loads(info_path.read_text())
    info["robot_type"] = "lekiwi"
    for key in FEATURES:
        info["features"][key]["names"] += list(VELOCITIES)
        info["features"][key]["shape"] = [d]
    info_path.write_text(json.dumps(info, indent=4))


def column_of(table: pa.Table, key: str) -> np.ndarray:
    col = table.column(key).combine_chunks()
    return np.asarray(col.flatten().to_numpy(zero_copy_only=False)).reshape(-1, col.type.list_size)


def raw_values(root: Path, key: str) -> np.ndarray:
    """All frames of a feature in the stored dtype (float32), for bit comparisons."""
    files = sorted(root.glob("data/chunk-*/file-*.parquet"))
    return np.concatenate([column_of(pq.read_table(f), key) for f in files])


@pytest.fixture()
def lekiwi(tmp_path: Path) -> Path:
    root = tmp_path / "lekiwi"
    generate_dataset(
        root,
        n_episodes=3,
        frames_per_episode=[30, 40, 25],
        joint_names=ARM,
        convention=lekiwi_conv(HOMING_A, RANGE_A),
        actual_lo=LO,
        actual_hi=HI,
        robot_type="lekiwi",
    )
    add_velocities(root)
    return root


# ------------------------------------------------------------------------------------------ gap 1


def test_mixed_feature_converts_positions_and_passes_the_rest_bit_identical(
    lekiwi: Path, tmp_path: Path
) -> None:
    old, new = lekiwi_conv(HOMING_A, RANGE_A), lekiwi_conv(HOMING_B, RANGE_B)
    rep = recalibrate_dataset(lekiwi, tmp_path / "dst", old, new, workers=2)
    assert rep.joint_names == dict.fromkeys(FEATURES, ARM)  # the converted joints
    assert set(rep.out_of_range["action"]) == set(ARM)
    for key in FEATURES:
        src, dst = raw_values(lekiwi, key), raw_values(tmp_path / "dst", key)
        assert dst.dtype == np.float32 and dst.shape == (95, 9)
        # velocities: the same bits (−0.0 and the subnormal included)
        np.testing.assert_array_equal(dst[:, 6:].view(np.uint32), src[:, 6:].view(np.uint32))
        # arm: exactly what the arm alone converts to
        expected, _ = recalibrate_values(src[:, :6].astype(np.float64), old.select(ARM), new.select(ARM))
        np.testing.assert_array_equal(dst[:, :6], expected.astype(np.float32))
        assert not np.array_equal(dst[:, :6], src[:, :6])
        # dataset stats of the whole feature recomputed from the new values, velocities included
        stats = json.loads((tmp_path / "dst/meta/stats.json").read_text())[key]
        np.testing.assert_array_equal(stats["min"], dst.min(axis=0).astype(np.float64))
        np.testing.assert_array_equal(stats["max"], dst.max(axis=0).astype(np.float64))
        assert stats["count"] == [95]
    # and back: A → B → A reproduces every value
    recalibrate_dataset(tmp_path / "dst", tmp_path / "back", new, old)
    for key in FEATURES:
        back, src = raw_values(tmp_path / "back", key), raw_values(lekiwi, key)
        np.testing.assert_array_equal(back.view(np.uint32), src.view(np.uint32))


def test_mixed_feature_through_the_cli_with_wheel_motors(
    lekiwi: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    write_calibration(tmp_path / "a.json", lekiwi_cals(HOMING_A, RANGE_A))
    write_calibration(tmp_path / "b.json", lekiwi_cals(HOMING_B, RANGE_B))
    code = main(
        ["dataset", "recalibrate", str(lekiwi), str(tmp_path / "dst"), "--old", str(tmp_path / "a.json"),
         "--new", str(tmp_path / "b.json")]
    )  # fmt: skip
    out, err = capsys.readouterr()
    assert (code, err) == (0, "")
    assert "95 frames" in out
    expected = recalibrate_dataset(
        lekiwi, tmp_path / "api", lekiwi_conv(HOMING_A, RANGE_A), lekiwi_conv(HOMING_B, RANGE_B)
    )
    assert expected.warnings == []
    for key in FEATURES:
        np.testing.assert_array_equal(all_values(tmp_path / "dst", key), all_values(tmp_path / "api", key))
    # the LeKiwi preset gives arm_gripper range_0_100, like LeRobot's LeKiwi
    assert preset_modes("lekiwi", ["arm_gripper", "arm_elbow_flex"], True) == {
        "arm_gripper": "range_0_100",
        "arm_elbow_flex": "degrees",
    }


def test_position_entry_without_calibration_is_an_error_naming_it(lekiwi: Path, tmp_path: Path) -> None:
    cals = lekiwi_cals(HOMING_B, RANGE_B)
    del cals["arm_wrist_roll"]
    partial = LeRobotConvention.from_calibrations(cals, preset_modes("lekiwi", list(cals)), "feetech")
    with pytest.raises(JointMismatchError, match=r"entry 'arm_wrist_roll.pos' not in the new calibration"):
        recalibrate_dataset(lekiwi, tmp_path / "dst", lekiwi_conv(HOMING_A, RANGE_A), partial)
    assert not (tmp_path / "dst").exists()
    # a feature with nothing to convert is refused too
    table = pa.table({"observation.velocity": pa.FixedSizeListArray.from_arrays(pa.array([0.5]), 1)})
    conv = lekiwi_conv(HOMING_A, RANGE_A)
    with pytest.raises(JointMismatchError, match=r"no joint-position entry .* entries: x.vel"):
        recalibrate_table(table, conv, conv, features={"observation.velocity": ["x.vel"]})


def test_recalibrate_table_keeps_nan_in_passed_through_entries() -> None:
    conv_a, conv_b = lekiwi_conv(HOMING_A, RANGE_A), lekiwi_conv(HOMING_B, RANGE_B)
    arm = conv_a.select(ARM).from_actual(np.full((2, 6), 2000.0))[0].astype(np.float32)
    nan = np.frombuffer(np.array([0x7FC01234], dtype=np.uint32).tobytes(), dtype=np.float32)[0]
    vel = np.array([[nan, 1.5, -0.0], [0.25, nan, 2.0]], dtype=np.float32)
    vals = np.concatenate([vel[:, :1], arm, vel[:, 1:]], axis=1)  # entries may come in any order
    names = ["x.vel", *(f"{j}.pos" for j in ARM), "y.vel", "theta.vel"]
    table = pa.table({"action": pa.FixedSizeListArray.from_arrays(pa.array(vals.reshape(-1)), 9)})
    out = column_of(recalibrate_table(table, conv_a, conv_b, features={"action": names}), "action")
    keep = [0, 7, 8]
    np.testing.assert_array_equal(out[:, keep].view(np.uint32), vals[:, keep].view(np.uint32))
    expected = conv_b.select(ARM).from_actual(np.full((2, 6), 2000.0))[0].astype(np.float32)
    np.testing.assert_array_equal(out[:, 1:7], expected)
    vals[1, 3] = np.nan  # NaN in a converted entry is still refused
    table = pa.table({"action": pa.FixedSizeListArray.from_arrays(pa.array(vals.reshape(-1)), 9)})
    with pytest.raises(FileFormatError, match=r"1 NaN or inf entries \(first at row 1, entry 3\)"):
        recalibrate_table(table, conv_a, conv_b, features={"action": names})


def test_inspect_mixed_feature_with_calibration(lekiwi: Path) -> None:
    rep = inspect_dataset(lekiwi, calibration=lekiwi_conv(HOMING_A, RANGE_A))
    by_joint = {(j.feature, j.joint): j for j in rep.joints}
    assert by_joint[("action", "x.vel")].range_lo is None
    assert by_joint[("action", "arm_gripper")].range_lo == pytest.approx(0.0)
    assert rep.flagged == ()


# ------------------------------------------------------------------------------------------ gap 2


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


# ------------------------------------------------------------------------------------------ gap 3


def test_data_without_episode_index_recomputes_dataset_stats(tmp_path: Path) -> None:
    src = tmp_path / "src"
    generate_dataset(
        src,
        n_episodes=4,
        frames_per_episode=[30, 40, 25, 12],
        convention=_so_conv(HOMING_A),
        actual_lo=LO,
        actual_hi=HI,
    )
    path = src / "data/chunk-000/file-001.parquet"  # episodes 2 and 3
    pf = pq.ParquetFile(path)
    parts = [pf.read_row_group(g).drop(["episode_index"]) for g in range(pf.metadata.num_row_groups)]
    with pq.ParquetWriter(path, parts[0].schema) as writer:
        for t in parts:
            writer.write_table(t, row_group_size=t.num_rows)
    old_episodes = pq.read_table(src / "meta/episodes/chunk-000/file-000.parquet").to_pylist()
    rep = recalibrate_dataset(src, tmp_path / "dst", _so_conv(HOMING_A), _so_conv(HOMING_B))
    assert rep.frames == 107
    assert rep.warnings[0] == (
        "data file data/chunk-000/file-001.parquet has no 'episode_index' column: meta/stats.json is "
        "recomputed from its 37 frames, but per-episode statistics cannot be updated for them"
    )
    assert rep.warnings[1].startswith(
        "meta/episodes/chunk-000/file-000.parquet: per-episode statistics of observation.state, action "
        "for 2 episode(s) (2, 3) could not be updated"
    )
    assert len(rep.warnings) == 2
    stats = json.loads((tmp_path / "dst/meta/stats.json").read_text())
    for key in FEATURES:
        values = all_values(tmp_path / "dst", key)
        assert stats[key]["count"] == [107]
        np.testing.assert_array_equal(stats[key]["min"], values.min(axis=0))
        np.testing.assert_array_equal(stats[key]["max"], values.max(axis=0))
        np.testing.assert_allclose(stats[key]["mean"], values.mean(axis=0), rtol=1e-12)
        np.testing.assert_allclose(stats[key]["std"], values.std(axis=0), rtol=1e-9)
    episodes = pq.read_table(tmp_path / "dst/meta/episodes/chunk-000/file-000.parquet").to_pylist()
    values = all_values(tmp_path / "dst", "action")
    # episodes 0 and 1 (first file) updated; 2 and 3 kept as they were
    np.testing.assert_array_equal(episodes[0]["stats/action/min"], values[:30].min(axis=0))
    for e in (2, 3):
        assert episodes[e]["stats/action/min"] == old_episodes[e]["stats/action/min"]


def _so_conv(homing: list[int]) -> LeRobotConvention:
    ranges = RANGE_A if homing is HOMING_A else RANGE_B
    return LeRobotConvention.from_calibrations(
        {n: MotorCalibration(i + 1, 0, homing[i], *ranges[i]) for i, n in enumerate(SO_ARM_JOINTS)},
        preset_modes("so101_follower", SO_ARM_JOINTS),
        "feetech",
    )
