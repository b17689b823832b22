from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq
import pytest
from dataset_testutil import (
    ARM,
    FEATURES,
    HOMING_A,
    HOMING_B,
    RANGE_A,
    RANGE_B,
    TICK_RAD,
    A,
    B,
    all_values,
    column,
    column_of,
    joint_map,
    lekiwi_cals,
    lekiwi_conv,
    raw_values,
    tree,
)
from hypothesis import given
from hypothesis import strategies as st

from robocal.dataset import (
    SO_ARM_JOINTS,
    generate_dataset,
    read_layout,
    recalibrate_dataset,
    recalibrate_table,
    recalibrate_values,
)
from robocal.dataset.lerobot import LeRobotConvention, preset_modes
from robocal.errors import FileFormatError, JointMismatchError, ShapeMismatchError, UsageError


@pytest.fixture(scope="module")
def src(tmp_path_factory: pytest.TempPathFactory) -> Path:
    root = tmp_path_factory.mktemp("engine") / "src"
    generate_dataset(
        root, n_episodes=5, frames_per_episode=[40, 55, 30, 61, 20], episodes_per_file=2, convention=A
    )
    return root


def test_generated_layout(src: Path) -> None:
    layout = read_layout(src)
    assert layout.data_files == (
        "data/chunk-000/file-000.parquet",
        "data/chunk-000/file-001.parquet",
        "data/chunk-000/file-002.parquet",
    )
    assert [pq.ParquetFile(src / f).metadata.num_row_groups for f in layout.data_files] == [2, 2, 1]
    assert layout.vector_feature("action").joint_names == SO_ARM_JOINTS
    assert layout.info["total_frames"] == 206
    schema = pq.read_schema(src / layout.data_files[0])
    assert schema.field("action").type == pa.list_(pa.float32(), 6)
    assert b"huggingface" in schema.metadata


def test_recalibrate_table_affine_golden() -> None:
    # A: shoulder_pan q = +1·tick·(raw − 2047); B: q = +1·tick·(raw − 2000) → q_B = q_A + 47 ticks.
    # shoulder_lift A dir −1 off 2000, B dir +1 off 2010: q_B = −q_A − 10 ticks.
    q_a = np.zeros((2, 6), dtype=np.float32)
    q_a[1, 0] = np.float32(100 * TICK_RAD)
    q_a[1, 1] = np.float32(100 * TICK_RAD)
    table = pa.table({"action": pa.FixedSizeListArray.from_arrays(pa.array(q_a.ravel()), 6)})
    out = recalibrate_table(table, {"action": A}, {"action": B})
    assert out.schema == table.schema
    got = np.asarray(out.column("action").combine_chunks().flatten().to_numpy()).reshape(2, 6)
    np.testing.assert_allclose(got[0, 0] / TICK_RAD, 47.0, atol=1e-4)
    np.testing.assert_allclose(got[1, 0] / TICK_RAD, 147.0, atol=1e-4)
    np.testing.assert_allclose(got[0, 1] / TICK_RAD, -10.0, atol=1e-4)
    np.testing.assert_allclose(got[1, 1] / TICK_RAD, -110.0, atol=1e-4)


def test_recalibrate_table_handles_sliced_columns() -> None:
    vals = np.arange(18, dtype=np.float32).reshape(3, 6)
    table = pa.table({"action": pa.FixedSizeListArray.from_arrays(pa.array(vals.ravel()), 6)}).slice(1, 2)
    same = recalibrate_table(table, {"action": A}, {"action": A})
    got = np.asarray(same.column("action").combine_chunks().flatten().to_numpy()).reshape(2, 6)
    np.testing.assert_allclose(got, vals[1:], atol=1e-5)


def test_recalibrate_table_width_mismatch() -> None:
    table = pa.table({"action": pa.FixedSizeListArray.from_arrays(pa.array(np.zeros(10, np.float32)), 5)})
    with pytest.raises(ShapeMismatchError, match="'action' has 5 entries per frame; expected 6"):
        recalibrate_table(table, {"action": A}, {"action": B})


def test_round_trip_preserves_everything(src: Path, tmp_path: Path) -> None:
    mid, back = tmp_path / "b", tmp_path / "a"
    rep1 = recalibrate_dataset(src, mid, A, B)
    rep2 = recalibrate_dataset(mid, back, B, A, workers=2)
    assert rep1.frames == rep2.frames == 206
    assert rep1.row_groups == rep2.row_groups == 5
    assert rep1.out_of_range["action"] == dict.fromkeys(SO_ARM_JOINTS, 0)
    assert tree(back) == tree(src)
    for rel in read_layout(src).data_files:
        s_pf, b_pf = pq.ParquetFile(src / rel), pq.ParquetFile(back / rel)
        assert b_pf.schema_arrow == s_pf.schema_arrow
        assert b_pf.schema_arrow.metadata == s_pf.schema_arrow.metadata
        assert [b_pf.metadata.row_group(i).num_rows for i in range(b_pf.metadata.num_row_groups)] == [
            s_pf.metadata.row_group(i).num_rows for i in range(s_pf.metadata.num_row_groups)
        ]
        assert b_pf.metadata.row_group(0).column(0).compression == "SNAPPY"
        for key in ("observation.state", "action"):
            np.testing.assert_allclose(column(back / rel, key), column(src / rel, key), atol=2e-6)
        s_t, b_t = pq.read_table(src / rel), pq.read_table(back / rel)
        for key in ("timestamp", "frame_index", "episode_index", "index", "task_index"):
            assert b_t.column(key).equals(s_t.column(key))
    # the middle dataset really differs: shoulder_pan shifted by 47 ticks
    np.testing.assert_allclose(
        all_values(mid, "action")[:, 0] - all_values(src, "action")[:, 0], 47 * TICK_RAD, atol=2e-6
    )
    video = "videos/observation.images.front/chunk-000/file-000.mp4"
    assert (back / video).stat().st_ino == (src / video).stat().st_ino  # hard-linked, not rewritten
    for rel in (
        "meta/info.json",
        "meta/tasks.parquet",
        "README.md",
        "videos/observation.images.front/chunk-000/file-000.mp4",
    ):
        assert (back / rel).read_bytes() == (src / rel).read_bytes()


def test_stats_recomputed(src: Path, tmp_path: Path) -> None:
    dst = tmp_path / "b"
    recalibrate_dataset(src, dst, A, B, features=["action"])
    stats = json.loads((dst / "meta/stats.json").read_text())
    old_stats = json.loads((src / "meta/stats.json").read_text())
    values = all_values(dst, "action")
    np.testing.assert_allclose(stats["action"]["min"], values.min(axis=0), rtol=1e-12)
    np.testing.assert_allclose(stats["action"]["max"], values.max(axis=0), rtol=1e-12)
    np.testing.assert_allclose(stats["action"]["mean"], values.mean(axis=0), rtol=1e-9)
    np.testing.assert_allclose(stats["action"]["std"], values.std(axis=0), rtol=1e-9)
    assert stats["action"]["count"] == [206]
    assert set(stats["action"]) == set(old_stats["action"])
    # features not converted keep their statistics byte for byte
    assert stats["observation.state"] == old_stats["observation.state"]
    assert stats["timestamp"] == old_stats["timestamp"]
    # observation.state was not converted
    np.testing.assert_array_equal(all_values(dst, "observation.state"), all_values(src, "observation.state"))
    eps = pq.read_table(dst / "meta/episodes/chunk-000/file-000.parquet").to_pylist()
    old_eps = pq.read_table(src / "meta/episodes/chunk-000/file-000.parquet")
    assert pq.read_schema(dst / "meta/episodes/chunk-000/file-000.parquet") == old_eps.schema
    ep3 = values[40 + 55 + 30 : 40 + 55 + 30 + 61]
    np.testing.assert_allclose(eps[3]["stats/action/min"], ep3.min(axis=0), rtol=1e-12)
    np.testing.assert_allclose(eps[3]["stats/action/mean"], ep3.mean(axis=0), rtol=1e-9)
    np.testing.assert_allclose(eps[3]["stats/action/q50"], np.quantile(ep3, 0.5, axis=0), rtol=1e-9)
    assert eps[3]["stats/action/count"] == [61]
    assert eps[3]["stats/observation.state/min"] == old_eps.to_pylist()[3]["stats/observation.state/min"]


def test_out_of_range_counted(tmp_path: Path) -> None:
    src = tmp_path / "src"
    generate_dataset(src, n_episodes=2, frames_per_episode=30, convention=A)
    lower = np.full(6, -np.inf)
    upper = np.full(6, np.inf)
    upper[2] = 0.0  # elbow_flex above 0 rad counts
    limited = type(B)(B.calibration, lower=lower, upper=upper, turn_raw=4096)
    rep = recalibrate_dataset(src, tmp_path / "dst", A, limited)
    expect = int((all_values(tmp_path / "dst", "action")[:, 2] > 0).sum())
    assert expect > 0
    assert rep.out_of_range["action"]["elbow_flex"] == expect
    assert rep.out_of_range["action"]["shoulder_pan"] == 0
    assert any("elbow_flex" in w for w in rep.warnings)


@given(
    st.lists(st.integers(0, 4095), min_size=6, max_size=6),
    st.lists(st.sampled_from([-1, 1]), min_size=6, max_size=6),
    st.lists(st.integers(-2047, 2047), min_size=1, max_size=30),
)
def test_table_round_trip_property(offsets: list[int], dirs: list[int], ticks: list[int]) -> None:
    other = joint_map(dirs, offsets)
    raw = np.array([[t + k for k in range(6)] for t in ticks], dtype=np.float64) + 2048
    q, _ = A.from_actual(raw)
    table = pa.table({"action": pa.FixedSizeListArray.from_arrays(pa.array(q.astype(np.float32).ravel()), 6)})
    back = recalibrate_table(recalibrate_table(table, A, other), other, A)
    assert back.schema == table.schema
    got = np.asarray(back.column("action").combine_chunks().flatten().to_numpy(), dtype=np.float64)
    np.testing.assert_allclose(got.reshape(-1, 6) / TICK_RAD, q.astype(np.float32) / TICK_RAD, atol=1e-3)


def test_failure_midway_leaves_no_dst(src: Path, tmp_path: Path) -> None:
    bad = tmp_path / "bad"
    generate_dataset(bad, n_episodes=4, frames_per_episode=20, episodes_per_file=1, convention=A)
    (bad / "data/chunk-000/file-002.parquet").write_bytes(b"PAR1 this is not parquet PAR1")
    for workers in (1, 2):
        dst = tmp_path / f"dst{workers}"
        with pytest.raises(FileFormatError, match=r"data file data/chunk-000/file-002.parquet"):
            recalibrate_dataset(bad, dst, A, B, workers=workers)
        assert not dst.exists()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["bad"]


def test_overwrite_replaces_only_at_the_end(src: Path, tmp_path: Path) -> None:
    dst = tmp_path / "dst"
    dst.mkdir()
    (dst / "keep.txt").write_text("old")
    with pytest.raises(UsageError, match="already exists; pass --overwrite"):
        recalibrate_dataset(src, dst, A, B)
    assert (dst / "keep.txt").read_text() == "old"
    rep = recalibrate_dataset(src, dst, A, B, overwrite=True)
    assert rep.frames == 206
    assert not (dst / "keep.txt").exists()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["dst"]


def _put_nan(root: Path) -> None:
    path = root / "data/chunk-000/file-000.parquet"
    table = pq.read_table(path)
    vals = column(path, "action").astype(np.float32)
    vals[3, 2] = np.nan
    col = pa.FixedSizeListArray.from_arrays(pa.array(vals.ravel()), 6)
    pq.write_table(table.set_column(1, table.schema.field(1), col), path)


@pytest.mark.parametrize(
    ("mutate", "exc", "message"),
    [
        (lambda r: (r / "meta/info.json").unlink(), FileFormatError, "missing meta/info.json"),
        (lambda r: (r / "meta/info.json").write_text("{not json"), FileFormatError, "invalid JSON"),
        (
            lambda r: (r / "meta/info.json").write_text('{"codebase_version": "v2.1", "features": {}}'),
            FileFormatError,
            "only LeRobot v3",
        ),
        (lambda r: [p.unlink() for p in r.glob("data/*/*.parquet")], FileFormatError, "no data/chunk-"),
        (
            lambda r: (r / "meta/stats.json").write_text("[1, 2"),
            FileFormatError,
            r"stats\.json: invalid JSON \(line 1, column 6\)",
        ),
        (
            lambda r: (r / "meta/episodes/chunk-000/file-000.parquet").write_bytes(b"junk"),
            FileFormatError,
            "episodes file meta/episodes/chunk-000/file-000.parquet: cannot read Parquet",
        ),
        (_put_nan, FileFormatError, r"data file data/chunk-000/file-000.parquet, row groups 0-0: .*NaN"),
    ],
)
def test_malformed_dataset(tmp_path: Path, mutate, exc: type[Exception], message: str) -> None:
    src = tmp_path / "src"
    generate_dataset(src, n_episodes=1, frames_per_episode=5, convention=A)
    mutate(src)
    with pytest.raises(exc, match=message):
        recalibrate_dataset(src, tmp_path / "dst", A, B)
    assert not (tmp_path / "dst").exists()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["src"]


def test_unknown_feature_and_joint_mismatch(src: Path, tmp_path: Path) -> None:
    with pytest.raises(
        UsageError,
        match=r"unknown feature 'observation.velocity'; float vector features: "
        r"observation.state, action",
    ):
        recalibrate_dataset(src, tmp_path / "d", A, B, features=["observation.velocity"])
    five = A.select(SO_ARM_JOINTS[:5])
    assert five.joint_names == SO_ARM_JOINTS[:5]
    with pytest.raises(
        JointMismatchError,
        match=r"feature 'observation.state': joint-position entry 'gripper.pos' not in the new "
        r"calibration \(its motors: shoulder_pan, ",
    ):
        recalibrate_dataset(src, tmp_path / "d", A, type(A)(five.calibration))
    with pytest.raises(UsageError, match="overlaps the source"):
        recalibrate_dataset(src, src / "inner", A, B)
    assert not (tmp_path / "d").exists()


def test_recalibrate_table_bad_inputs() -> None:
    vals = pa.FixedSizeListArray.from_arrays(pa.array(np.zeros(12, np.float32)), 6)
    table = pa.table({"action": vals})
    with pytest.raises(UsageError, match=r"feature 'action': no new calibration for it \(given for: obs\)"):
        recalibrate_table(table, {"action": A}, {"obs": B})
    with pytest.raises(
        UsageError, match=r"none of the columns observation\.state, action; name the features"
    ):
        recalibrate_table(pa.table({"joints": vals}), A, B)
    with pytest.raises(UsageError, match=r"expected a pyarrow\.Table, got FixedSizeListArray"):
        recalibrate_table(vals, A, B)  # type: ignore[arg-type]
    with pytest.raises(UsageError, match="the old calibration is a str; expected a ValueConvention"):
        recalibrate_table(table, "a.json", B)  # type: ignore[arg-type]
    ints = pa.FixedSizeListArray.from_arrays(pa.array(np.zeros(12, np.int64)), 6)
    with pytest.raises(FileFormatError, match=r"'action': expected fixed_size_list<float>, found fixed_size"):
        recalibrate_table(pa.table({"action": ints}), A, B)


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
