from __future__ import annotations

import json
import shutil
from pathlib import Path
from typing import Any

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq
import pytest
from dataset_testutil import (
    FEATURES,
    HI,
    HOMING_A,
    HOMING_B,
    LO,
    RANGE_A,
    RANGE_B,
    all_values,
    cals,
    lekiwi_cals,
    lekiwi_conv,
    tree,
)

from robocal.cli.main import main
from robocal.core.jointmap import RobotCalibration
from robocal.core.lerobot import LegacyCalibration
from robocal.dataset import (
    SO_ARM_JOINTS,
    generate_dataset,
    recalibrate_dataset,
)
from robocal.dataset.lerobot import LeRobotConvention, preset_modes
from robocal.formats import write_calibration as write_joint_map
from robocal.lerobot import MotorCalibration, write_calibration
from robocal.lerobot.legacy import write_legacy


@pytest.fixture(scope="module")
def files(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    d = tmp_path_factory.mktemp("cli")
    write_calibration(d / "a.json", cals(HOMING_A, RANGE_A))
    write_calibration(d / "b.json", cals(HOMING_B, RANGE_B))
    conv_a = LeRobotConvention.from_calibrations(
        cals(HOMING_A, RANGE_A), preset_modes("so101_follower", SO_ARM_JOINTS), "feetech"
    )
    generate_dataset(
        d / "src",
        n_episodes=3,
        frames_per_episode=[30, 40, 25],
        convention=conv_a,
        actual_lo=LO,
        actual_hi=HI,
    )
    return {"a": d / "a.json", "b": d / "b.json", "src": d / "src", "dir": d}


def run(capsys: pytest.CaptureFixture[str], *args: str) -> tuple[int, str, str]:
    code = main([str(a) for a in args])
    out, err = capsys.readouterr()
    return code, out, err


def _recalibrate_to_joint_map(
    files: dict[str, Path], jm: RobotCalibration, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """Write ``jm`` as ``tmp_path/jm.yaml`` and recalibrate the source dataset from calibration a into it
    (``tmp_path/rad``, joint-frame radians); asserts a clean exit."""
    write_joint_map(tmp_path / "jm.yaml", jm, "robocal")
    code, _, err = run(
        capsys, "dataset", "recalibrate", files["src"], tmp_path / "rad", "--old", files["a"], "--new",
        tmp_path / "jm.yaml",
    )  # fmt: skip
    assert (code, err) == (0, "")


@pytest.mark.slow
def test_recalibrate_and_back(
    files: dict[str, Path], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    mid, back = tmp_path / "b", tmp_path / "a"
    code, out, err = run(
        capsys,
        "dataset",
        "recalibrate",
        files["src"],
        mid,
        "--old",
        files["a"],
        "--new",
        files["b"],
        "--robot",
        "so101_follower",
        "--workers",
        "2",
    )
    assert (code, err) == (0, "")
    assert f"wrote {mid}: 95 frames in 2 files, 3 row groups; features observation.state, action" in out
    # robot type from info.json when --robot is not given
    code, _, err = run(capsys, "dataset", "recalibrate", mid, back, "--old", files["b"], "--new", files["a"])
    assert (code, err) == (0, "")
    assert tree(back) == tree(files["src"])
    for key in ("observation.state", "action"):
        np.testing.assert_array_equal(all_values(back, key), all_values(files["src"], key))


def test_out_of_range_exit_1(
    files: dict[str, Path], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    narrow = cals(HOMING_B, RANGE_B)
    narrow["elbow_flex"] = MotorCalibration(3, 0, -90, 1500, 2500)
    write_calibration(tmp_path / "narrow.json", narrow)
    code, _, err = run(
        capsys,
        "dataset",
        "recalibrate",
        files["src"],
        tmp_path / "n",
        "--old",
        files["a"],
        "--new",
        tmp_path / "narrow.json",
        "--features",
        "action",
    )
    assert code == 1
    lines = err.strip().splitlines()
    assert len(lines) == 1
    assert lines[0].startswith(
        "warning: action: values outside the new calibrated range (clamped where the "
        "mode clamps): elbow_flex "
    )
    count = int(lines[0].rsplit(" ", 1)[1])
    assert 0 < count < 95


def test_mode_change_and_old_modes(
    files: dict[str, Path], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    # recorded in degrees (SO default), converted to range_m100_100 for the same calibration
    code, _, err = run(
        capsys,
        "dataset",
        "recalibrate",
        files["src"],
        tmp_path / "r",
        "--old",
        files["a"],
        "--new",
        files["a"],
        "--no-use-degrees",
        "--old-modes",
        ",".join(f"{j}=degrees" for j in SO_ARM_JOINTS[:5]),
    )
    assert (code, err) == (0, "")
    old = all_values(files["src"], "observation.state")
    new = all_values(tmp_path / "r", "observation.state")
    # shoulder_lift: degrees around mid 2000 of 1000..3000 → (ticks / 1000)·100
    np.testing.assert_allclose(new[:, 1], old[:, 1] * 4095 / 360 / 1000 * 100, atol=0.1 + 1e-6)
    np.testing.assert_array_equal(new[:, 5], old[:, 5])  # gripper stays range_0_100


def test_joint_map_and_legacy_inputs(
    files: dict[str, Path], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    # canonical joint map (radians) → LeRobot current, through the actual encoder position
    tick = 2 * np.pi / 4096
    jm = RobotCalibration(SO_ARM_JOINTS, [1, -1, 1, 1, 1, 1], [2000, 2100, 1950, 2050, 2048, 1900], tick)
    _recalibrate_to_joint_map(files, jm, tmp_path, capsys)
    rad = all_values(tmp_path / "rad", "observation.state")
    deg = all_values(files["src"], "observation.state")
    # shoulder_pan: degrees mid 1925 → present → actual = present + 100 → q = (actual − 2000)·tick
    present = np.round(deg[:, 0] * 4095 / 360 + 1925)
    np.testing.assert_allclose(rad[:, 0], (present + 100 - 2000) * tick, atol=1e-6)
    # legacy DEGREE file → LeRobot current
    legacy = LegacyCalibration(SO_ARM_JOINTS, [-2048] * 6, [0] * 6, [0] * 6, [1024] * 6, ["DEGREE"] * 6)
    write_legacy(tmp_path / "legacy.json", legacy)
    code, _, err = run(
        capsys,
        "dataset",
        "recalibrate",
        files["src"],
        tmp_path / "leg",
        "--old",
        files["a"],
        "--new",
        tmp_path / "legacy.json",
        "--features",
        "observation.state",
    )
    assert (code, err) == (0, "")
    leg = all_values(tmp_path / "leg", "observation.state")
    np.testing.assert_allclose(leg[:, 0], (present + 100 - 2048) / 2048 * 180, atol=1e-4)


def _one_error(err: str, needle: str) -> None:
    lines = err.strip().splitlines()
    assert len(lines) == 1, err
    assert lines[0].startswith("error: ")
    assert needle in lines[0]


@pytest.mark.parametrize(
    ("case", "needle"),
    [
        ("no_info", "missing meta/info.json"),
        (
            "unknown_feature",
            "unknown feature 'observation.effort'; float vector features: observation.state, action",
        ),
        ("joint_mismatch", "joint-position entry 'gripper.pos' not in the new calibration"),
        ("dst_exists", "already exists; pass --overwrite"),
        (
            "bad_mode",
            "--modes: mode 'radians' for 'gripper' is not one of degrees, range_m100_100, range_0_100",
        ),
        ("unknown_joint_mode", "--modes: joint(s) thumb not in the dataset"),
        ("no_modes", "is a LeRobot calibration: pass --robot or --motor-family"),
        ("bad_compat", "--compat 'fast': expected lerobot or exact"),
        ("missing_old", "no such file"),
        ("bad_workers", "--workers 0: expected a positive number"),
        # before: an empty --robot fell back to meta/info.json's robot_type and the run went on (exit 0)
        ("empty_robot", "--robot '' is empty: name the LeRobot robot type (so101_follower, koch_follower, ...)"),
        ("blank_robot", "--robot ' ' is empty: name the LeRobot robot type (so101_follower, koch_follower, ...)"),
        # before: an empty --modes / --old-modes was read as no override, silently
        ("empty_modes", "--modes '': expected name=value pairs separated by commas"),
        ("empty_old_modes", "--old-modes '': expected name=value pairs separated by commas"),
        # before: numpy's "invalid value encountered in cast" on stderr, the null row's frame counted in some
        # episode, exit 0 (a float column: truncated to the episode below); as dataset inspect / health say
        (
            "null_episode",
            "data file data/chunk-000/file-000.parquet: column 'episode_index' is int64 with null rows; expected "
            "an integer episode number in every row",
        ),
        (
            "float_episode",
            "data file data/chunk-000/file-000.parquet: column 'episode_index' is double; expected an integer "
            "episode number in every row",
        ),
        # the same in meta/episodes (was an internal error, exit 70: int(None))
        (
            "null_meta_episode",
            "episodes file meta/episodes/chunk-000/file-000.parquet: column 'episode_index' is int64 with null rows",
        ),
    ],
)
def test_bad_input_exit_2(
    files: dict[str, Path], tmp_path: Path, capsys: pytest.CaptureFixture[str], case: str, needle: str
) -> None:
    src, dst = files["src"], tmp_path / "dst"
    old, new = files["a"], files["b"]
    extra: list[str] = []
    if case == "no_info":
        src = tmp_path / "empty"
        (src / "data").mkdir(parents=True)
    elif case == "unknown_feature":
        extra = ["--features", "observation.effort"]
    elif case == "joint_mismatch":
        five = cals(HOMING_B, RANGE_B)
        del five["gripper"]
        write_calibration(tmp_path / "five.json", five)
        new = tmp_path / "five.json"
    elif case == "dst_exists":
        dst.mkdir()
    elif case == "bad_mode":
        extra = ["--modes", "gripper=radians"]
    elif case == "unknown_joint_mode":
        extra = ["--modes", "thumb=degrees"]
    elif case == "no_modes":
        info = json.loads((src / "meta/info.json").read_text())
        src = tmp_path / "copy"
        shutil.copytree(files["src"], src)
        info["robot_type"] = "mystery_arm"
        (src / "meta/info.json").write_text(json.dumps(info))
    elif case == "bad_compat":
        extra = ["--compat", "fast"]
    elif case == "missing_old":
        old = tmp_path / "nope.json"
    elif case == "bad_workers":
        extra = ["--workers", "0"]
    elif case in ("empty_robot", "blank_robot"):
        extra = ["--robot", "" if case == "empty_robot" else " "]
    elif case in ("empty_modes", "empty_old_modes"):
        extra = ["--modes" if case == "empty_modes" else "--old-modes", ""]
    elif case in ("null_episode", "float_episode"):
        src = tmp_path / "copy"
        shutil.copytree(files["src"], src)
        path = src / "data/chunk-000/file-000.parquet"
        table = pq.read_table(path)
        eps: list[Any] = table.column("episode_index").to_pylist()
        if case == "null_episode":
            eps[7] = None
        else:
            eps = [e + 0.5 for e in eps]
        i = table.schema.get_field_index("episode_index")
        typ = pa.int64() if case == "null_episode" else pa.float64()
        pq.write_table(table.set_column(i, "episode_index", pa.array(eps, typ)), path)
    elif case == "null_meta_episode":
        src = tmp_path / "copy"
        shutil.copytree(files["src"], src)
        path = src / "meta/episodes/chunk-000/file-000.parquet"
        table = pq.read_table(path)
        i = table.schema.get_field_index("episode_index")
        eps = [None, *table.column("episode_index").to_pylist()[1:]]
        pq.write_table(table.set_column(i, "episode_index", pa.array(eps, pa.int64())), path)
    before = sorted(p.name for p in tmp_path.iterdir())
    code, _, err = run(capsys, "dataset", "recalibrate", src, dst, "--old", old, "--new", new, *extra)
    assert code == 2
    _one_error(err, needle)
    assert sorted(p.name for p in tmp_path.iterdir()) == before  # no DST, no temporary folder left


def test_inspect(files: dict[str, Path], tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    code, out, err = run(capsys, "dataset", "inspect", files["src"], "--calibration", files["a"])
    assert (code, err) == (0, "")
    assert "95 frames" in out and "shoulder_pan" in out
    # the same data read with a calibration whose elbow_flex range is far too narrow
    narrow = cals(HOMING_A, RANGE_A)
    narrow["elbow_flex"] = MotorCalibration(3, 0, 60, 1900, 2150)
    write_calibration(tmp_path / "narrow.json", narrow)
    code, out, err = run(
        capsys, "dataset", "inspect", files["src"], "--calibration", tmp_path / "narrow.json"
    )
    assert code == 1
    lines = err.strip().splitlines()
    assert len(lines) == 2
    assert lines[0].startswith("warning: observation.state elbow_flex: ")
    assert lines[0].endswith("value(s) outside the calibrated range — check the calibration")
    assert lines[1].startswith("warning: action elbow_flex: ")
    # a dataset stored in raw ticks read as degrees: values beyond ±180° and half-turn jumps
    raw = tmp_path / "raw"
    generate_dataset(raw, n_episodes=1, frames_per_episode=20, actual_lo=LO, actual_hi=HI)
    code, out, err = run(
        capsys, "dataset", "inspect", raw, "--robot", "so101_follower", "--features", "action"
    )
    assert code == 1
    assert "warning: action shoulder_pan: 20 value(s) outside the calibrated range" in err
    code, _, err = run(capsys, "dataset", "inspect", tmp_path)
    assert code == 2
    _one_error(err, "missing meta/info.json")


@pytest.mark.parametrize(
    ("option", "needle"),
    [
        (["--robot", ""], "--robot '' is empty: name the LeRobot robot type (so101_follower, koch_follower, ...), "
         "or leave --robot out to use meta/info.json's robot_type"),
        (["--modes", ""], "--modes '': expected name=value pairs separated by commas"),
    ],
)
def test_inspect_refuses_an_empty_robot_or_modes(
    files: dict[str, Path], capsys: pytest.CaptureFixture[str], option: list[str], needle: str
) -> None:
    """Before, ``--robot ""`` fell back to meta/info.json's robot_type and ``--modes ""`` to the preset (exit 0)."""
    code, out, err = run(capsys, "dataset", "inspect", files["src"], "--calibration", files["a"], *option)
    assert (code, out) == (2, "")
    _one_error(err, needle)


@pytest.mark.slow
def test_overwrite_and_joint_map_inspect(
    files: dict[str, Path], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    dst = tmp_path / "dst"
    dst.mkdir()
    (dst / "stale.txt").write_text("x")
    args = ["dataset", "recalibrate", files["src"], dst, "--old", files["a"], "--new", files["b"]]
    code, _, err = run(capsys, *args)
    assert code == 2
    _one_error(err, f"destination {dst} already exists; pass --overwrite to replace it")
    code, _, err = run(capsys, *args, "--overwrite")
    assert (code, err) == (0, "")
    assert not (dst / "stale.txt").exists()
    assert tree(dst) == tree(files["src"])
    # a dataset in joint-frame radians inspected with its joint map: no jumps, no range known
    jm = RobotCalibration(SO_ARM_JOINTS, [1] * 6, [2048] * 6, 2 * np.pi / 4096)
    _recalibrate_to_joint_map(files, jm, tmp_path, capsys)
    code, out, err = run(
        capsys, "dataset", "inspect", tmp_path / "rad", "--calibration", tmp_path / "jm.yaml"
    )
    assert (code, err) == (0, "")
    assert "95 frames" in out


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


def test_the_job_takes_one_request_and_writes_what_the_cli_writes(
    files: dict[str, Path], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    from robocal.workflows.dataset.job import DatasetOptions, RecalibrateRequest, recalibrate

    args = ["dataset", "recalibrate", files["src"], tmp_path / "cli", "--old", files["a"], "--new", files["b"]]
    code, _, err = run(capsys, *args)
    assert (code, err) == (0, "")
    done: list[int] = []
    request = RecalibrateRequest(
        files["src"], tmp_path / "py", files["a"], files["b"], options=DatasetOptions(robot="so101_follower")
    )
    report = recalibrate(request, on_file_done=lambda _path, frames: done.append(frames))
    assert (report.frames, sum(done)) == (95, 95)
    assert tree(tmp_path / "py") == tree(tmp_path / "cli")
    for name in tree(tmp_path / "cli"):
        cli_file, py_file = tmp_path / "cli" / name, tmp_path / "py" / name
        assert cli_file.is_dir() or py_file.read_bytes() == cli_file.read_bytes(), name
