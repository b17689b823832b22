"""LeRobot calibration files users and LeRobot itself committed (tests/fixtures/lerobot/README.md), issue #15."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from robocal.cli.main import main
from robocal.core.lerobot import ranges_beyond_one_turn
from robocal.formats import read_calibration as read_joint_map
from robocal.lerobot import MotorCalibration, legacy, normalize, read_calibration

FIX = Path(__file__).resolve().parent.parent / "fixtures" / "lerobot"
MOTOR_CONFIG = FIX.parent / "lite_motor_config" / "robot_configuration.json"
SO_TRANSFORM = "shoulder_lift_new = -(old - 90)"


def run(capsys: pytest.CaptureFixture[str], *args: object) -> tuple[int, str, str]:
    code = main([str(a) for a in args])
    out, err = capsys.readouterr()
    return code, out, err


# ------------------------------------------------------------------------- the official files, both families
def test_official_so100_follower_migrates_with_the_so_transform(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "so100.json"
    code, stdout, err = run(
        capsys,
        "lerobot",
        "migrate",
        FIX / "so100_main_follower_legacy.json",
        "--vendor",
        "feetech",
        "--out",
        out,
    )
    assert (
        code == 1
    )  # shoulder_lift and wrist_roll are inverted DEGREE joints: LeRobot's DEGREES ignores that
    assert SO_TRANSFORM in stdout and "Koch" not in stdout
    assert [line.split(":")[1].strip() for line in err.splitlines()] == ["shoulder_lift", "wrist_roll"]
    cals = read_calibration(out)
    assert cals["gripper"] == MotorCalibration(6, 0, 0, 2044, 3454)  # inside one turn: kept as it is
    assert cals["shoulder_pan"] == MotorCalibration(1, 0, (1764 - 2047 + 2048) % 4096 - 2048, 0, 4094)
    assert ranges_beyond_one_turn(cals) == []


@pytest.mark.parametrize("name", ["koch_main_follower_legacy.json", "koch_main_leader_legacy.json"])
def test_koch_migrate_prints_only_the_koch_line(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], name: str
) -> None:
    code, stdout, err = run(capsys, "lerobot", "migrate", FIX / name, "--vendor", "dynamixel")
    assert code == 0 and err == ""
    assert SO_TRANSFORM not in stdout and "SO-100/SO-101 datasets" not in stdout
    assert "old Koch datasets (legacy degrees): LeRobot documents no value transform for Koch arms" in stdout
    data = json.loads(stdout[: stdout.rindex("}") + 1])
    assert data["shoulder_pan"] == {
        "id": 1,
        "drive_mode": 1,
        "homing_offset": 2048 + 2047,
        "range_min": 0,
        "range_max": 4094,
    }


def test_official_koch_files_convert_exactly(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    code, _out, _err = run(
        capsys, "convert", FIX / "koch_main_follower_legacy.json", tmp_path / "k.yaml", "--to", "robocal"
    )
    assert code == 0
    rc = read_joint_map(tmp_path / "k.yaml").calibration
    cal = legacy.read_legacy(FIX / "koch_main_follower_legacy.json")
    raw = legacy.revert_calibration(np.array([[0.0] * 6, [30.0, -45.0, 90.0, 10.0, -120.0, 5.0]]), cal)
    np.testing.assert_allclose(rc.to_joint(raw), np.deg2rad(legacy.apply_calibration(raw, cal)), atol=1e-12)


# --------------------------------------------------- a LINEAR gripper: convert the DEGREE joints, name it
def test_convert_legacy_so100_with_linear_gripper_converts_the_degree_joints(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    dst = tmp_path / "so100.yaml"
    code, _out, err = run(capsys, "convert", FIX / "so100_main_follower_legacy.json", dst, "--to", "robocal")
    assert code == 1  # finished with warnings
    assert err.strip().splitlines() == [
        f"warning: {FIX / 'so100_main_follower_legacy.json'}: LINEAR motor(s) gripper left out "
        "(percent of a span, not a joint angle)"
    ]
    rc = read_joint_map(dst).calibration
    assert list(rc.joint_names) == ["shoulder_pan", "shoulder_lift", "elbow_flex", "wrist_flex", "wrist_roll"]
    cal = legacy.read_legacy(FIX / "so100_main_follower_legacy.json")
    raw = legacy.revert_calibration(
        np.array([[0.0] * 5 + [50.0], [30.0, -45.0, 90.0, 10.0, -120.0, 5.0]]), cal
    )
    np.testing.assert_allclose(
        rc.to_joint(raw[:, :5]), np.deg2rad(legacy.apply_calibration(raw, cal)[:, :5]), atol=1e-12
    )


def test_legacy_file_of_only_linear_motors_is_still_refused(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    src = tmp_path / "lin.json"
    src.write_text(json.dumps({"homing_offset": [0], "drive_mode": [0], "start_pos": [10], "end_pos": [900],
                               "calib_mode": ["LINEAR"], "motor_names": ["gripper"]}))  # fmt: skip
    code, _out, err = run(capsys, "convert", src, tmp_path / "x.yaml", "--to", "robocal")
    assert code == 2 and "LINEAR motor(s) gripper are not convertible" in err
    assert not (tmp_path / "x.yaml").exists()


# ------------------------------------------------------------------------------- a range beyond one turn
def test_migrate_rehomes_a_linear_range_beyond_one_turn_and_names_it(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    src = FIX / "so100_follower_gripper_beyond_turn_legacy.json"
    out = tmp_path / "cur.json"
    code, _stdout, err = run(capsys, "lerobot", "migrate", src, "--vendor", "feetech", "--out", out)
    assert code == 1
    assert (
        "warning: gripper: legacy LINEAR range 3426..4811 goes beyond one turn of a 4096-tick servo (0..4095); "
        "re-homed to homing_offset -2025, range 1355..2740"
    ) in err
    cals = read_calibration(out)
    assert cals["gripper"] == MotorCalibration(6, 0, -2025, 1355, 2740)
    assert ranges_beyond_one_turn(cals) == []
    # the same percentages as LeRobot's legacy LINEAR read, through the Feetech firmware homing
    cal = legacy.read_legacy(src)
    for unwrapped in (3426, 3500, 4095, 4096, 4500, 4811):
        present = (unwrapped % 4096 + 2025) % 4096  # Present = Actual − Homing_Offset, one turn
        legacy_pct = float((unwrapped - 3426) / (4811 - 3426) * 100)
        assert float(normalize(present, cals["gripper"], "range_0_100")) == pytest.approx(
            legacy_pct, abs=1e-12
        )
    assert legacy.read_legacy(src).calib_mode[5] == "LINEAR" and cal.end_pos[5] == 4811


def test_migrate_refuses_a_linear_span_of_a_full_turn(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    data = json.loads((FIX / "so100_follower_gripper_beyond_turn_legacy.json").read_text())
    data["end_pos"][5] = 3426 + 4200
    src = tmp_path / "wide.json"
    src.write_text(json.dumps(data))
    code, _out, err = run(
        capsys, "lerobot", "migrate", src, "--vendor", "feetech", "--out", tmp_path / "o.json"
    )
    assert code == 2
    assert err.strip() == (
        "error: motor 'gripper': LINEAR start_pos..end_pos 3426..7626 spans 4200 ticks, a full turn or more of a "
        "4096-tick servo; no range of one turn holds it (recalibrate this motor)"
    )
    assert not (tmp_path / "o.json").exists()


GRIPPER_WARNING = (
    "warning: motor 'gripper' (id 6): range_min..range_max 3426..4811 is beyond one turn of a 4096-tick feetech "
    "servo (0..4095); positions of one turn only cover 0..48 % of it; LeRobot 0.6.1 accepts it unchecked; "
    "recalibrate the motor (or re-home the range)"
)


def test_reader_accepts_like_lerobot_and_the_check_names_the_motor() -> None:
    cals = read_calibration(FIX / "so101_follower_current_gripper_beyond_turn.json")  # LeRobot loads it too
    assert cals["gripper"].range_max == 4811
    assert ranges_beyond_one_turn(cals) == [GRIPPER_WARNING.removeprefix("warning: ")]
    assert ranges_beyond_one_turn(read_calibration(FIX / "so101_follower_current.json")) == []


def test_the_workflow_names_the_arms_vendor_in_the_range_warning() -> None:
    from robocal.workflows.lerobot import range_warnings, robot_spec

    cals = read_calibration(FIX / "so101_follower_current_gripper_beyond_turn.json")
    assert range_warnings(robot_spec("so101_follower"), cals) == [GRIPPER_WARNING.removeprefix("warning: ")]
    koch = range_warnings(robot_spec("koch_follower"), {"gripper": cals["gripper"]})
    assert koch == [GRIPPER_WARNING.removeprefix("warning: ").replace("4096-tick feetech", "4096-tick dynamixel")]


def test_export_urdf_flags_a_range_beyond_one_turn(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    base = ["lerobot", "export-urdf", "--robot", "so101_follower", "--out"]
    code, _out, err = run(capsys, *base, tmp_path / "a.yaml", "--file", FIX / "so101_follower_current.json")
    assert code == 1 and GRIPPER_WARNING not in err  # (exit 1: the range-mode gripper is not exported)
    code, _out, err = run(
        capsys, *base, tmp_path / "b.yaml", "--file", FIX / "so101_follower_current_gripper_beyond_turn.json"
    )
    assert code == 1 and GRIPPER_WARNING in err.splitlines()


def test_show_and_check_flag_a_range_beyond_one_turn(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    f = FIX / "so101_follower_current_gripper_beyond_turn.json"
    code, out, err = run(capsys, "lerobot", "show", "--robot", "so101_follower", "--port", "sim", "--file", f)
    assert code == 0 and GRIPPER_WARNING in err.splitlines()
    assert out.splitlines()[0].startswith("reading  shoulder_pan")
    code, out, err = run(
        capsys, "lerobot", "check", "--robot", "so101_follower", "--port", "sim", "--file", f
    )
    assert code == 1 and GRIPPER_WARNING in err.splitlines()


# ------------------------------------------------------------------------ a motor configuration is no calibration
@pytest.mark.parametrize("extra", [[], ["--from", "lite-json"]])
def test_lite_motor_configuration_is_named_as_such(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], extra: list[str]
) -> None:
    code, _out, err = run(capsys, "convert", MOTOR_CONFIG, tmp_path / "x.yaml", "--to", "robocal", *extra)
    assert code == 2
    assert err.strip() == (
        f"error: {MOTOR_CONFIG}: this is a motor configuration (per-joint position_controller, current_controller "
        "settings, like the Berkeley Humanoid Lite's robot_configuration.json), not a calibration"
    )
    assert "Infinity" not in err and not (tmp_path / "x.yaml").exists()


@pytest.mark.parametrize(("start", "end"), [(2100, 3300), (3300, 2100)])
def test_migrate_keeps_the_direction_of_a_linear_gripper(tmp_path: Path, start: int, end: int) -> None:
    """Legacy LINEAR is 0 % at start_pos; a start_pos above end_pos must not flip the gripper on migration."""
    from robocal.workflows.lerobot import legacy_to_current

    cal = legacy.LegacyCalibration(["gripper"], [0], [0], [start], [end], ["LINEAR"])
    cals, warnings = legacy_to_current(cal, "feetech")
    assert warnings == []
    assert cals["gripper"] == MotorCalibration(1, int(start > end), 0, 2100, 3300)
    raw = np.array([2100, 2400, 2700, 3300])
    np.testing.assert_allclose(
        normalize(raw, cals["gripper"], "range_0_100"),
        legacy.apply_calibration(raw[:, None], cal)[:, 0],
        atol=1e-12,
    )


def test_writing_a_range_beyond_one_turn_warns_naming_the_motor(tmp_path: Path) -> None:
    from robocal.formats.lerobot import LeRobotRangeWarning
    from robocal.lerobot import write_calibration

    cals = read_calibration(FIX / "so101_follower_current_gripper_beyond_turn.json")
    out = tmp_path / "w.json"
    with pytest.warns(
        LeRobotRangeWarning, match=r"w\.json: motor 'gripper' \(id 6\): range_min..range_max 3426..4811"
    ):
        write_calibration(out, cals)
    assert read_calibration(out) == cals  # written as given, like LeRobot
