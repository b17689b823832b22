from __future__ import annotations

import json
import math
import shutil
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from robocal.core import RobotCalibration
from robocal.errors import FileFormatError, JointMismatchError, UsageError
from robocal.formats import CalibrationFile, detect_format, read_calibration, write_calibration
from robocal.formats.urdf import read_urdf

EXAMPLES = Path(__file__).resolve().parents[2] / "examples" / "lite"
URDF = EXAMPLES / "lite_bimanual.urdf"

names = st.text("abcdefghijklmnopqrstuvwxyz_", min_size=1, max_size=12)
offsets = st.floats(-10.0, 10.0, allow_nan=False, allow_infinity=False)


@st.composite
def calibration_files(draw: st.DrawFn) -> CalibrationFile:
    joint_names = draw(st.lists(names, min_size=1, max_size=10, unique=True))
    n = len(joint_names)
    dirs = draw(st.lists(st.sampled_from([-1, 1]), min_size=n, max_size=n))
    offs = draw(st.lists(offsets, min_size=n, max_size=n))
    ids = draw(st.lists(st.integers(0, 255), min_size=n, max_size=n, unique=True))
    return CalibrationFile(
        RobotCalibration(joint_names, dirs, offs), dict(zip(joint_names, ids, strict=False))
    )


@pytest.mark.parametrize("fmt", ["lite-json", "lite-yaml", "robocal", "ros2-transmission"])
@settings(suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(cf=calibration_files())
def test_write_read_identical(tmp_path: Path, fmt: str, cf: CalibrationFile) -> None:
    path = tmp_path / f"cal-{fmt}.out"
    path.unlink(missing_ok=True)
    assert write_calibration(path, cf, fmt) == fmt
    back = read_calibration(path)
    assert back.fmt == fmt
    assert back.calibration.joint_names == cf.calibration.joint_names
    np.testing.assert_array_equal(back.calibration.direction, cf.calibration.direction)
    np.testing.assert_array_equal(back.calibration.homing_offset, cf.calibration.homing_offset)  # bit-exact
    if fmt != "ros2-transmission":
        assert dict(back.ids) == dict(cf.ids)
    # writing what was read gives the same bytes
    before = path.read_bytes()
    write_calibration(path, back, fmt)
    assert path.read_bytes() == before


@settings(suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(offs=st.lists(offsets, min_size=14, max_size=14))
def test_berkeley_round_trip_through_urdf(tmp_path: Path, offs: list[float]) -> None:
    urdf = read_urdf(URDF)
    order = urdf.calibration_joint_names()
    dirs = [urdf.direction(n) for n in order]
    cal = RobotCalibration(order, dirs, offs)
    path = tmp_path / "berkeley.yaml"
    write_calibration(path, cal, "berkeley-offsets")
    assert detect_format(path) == "berkeley-offsets"
    back = read_calibration(path, urdf=urdf)
    np.testing.assert_array_equal(back.calibration.homing_offset, offs)
    assert back.calibration.joint_names == order
    assert back.ids["left_shoulder_pitch"] == 11


def test_berkeley_values_are_joint_frame(tmp_path: Path) -> None:
    urdf = read_urdf(URDF)
    path = tmp_path / "b.yaml"
    path.write_text("position_offsets: [" + ", ".join(["0.5"] * 14) + "]\n")
    back = read_calibration(path, urdf=urdf)
    # left_shoulder_pitch has direction -1: homing_offset = direction * off = -0.5
    assert back.calibration.joint_map("left_shoulder_pitch").homing_offset == -0.5
    assert back.calibration.joint_map("left_shoulder_yaw").homing_offset == 0.5
    with pytest.raises(UsageError, match=r"positional .*pass --joints .*--robot NAME"):
        read_calibration(path)
    with pytest.raises(JointMismatchError, match="14 offsets but 2 joints"):
        read_calibration(path, urdf=urdf, joint_order=["left_shoulder_pitch", "left_shoulder_roll"])


def test_lite_yaml_update_in_place_keeps_comments_and_changes_one_line(tmp_path: Path) -> None:
    path = tmp_path / "calibration.yaml"
    shutil.copy(EXAMPLES / "calibration.yaml", path)
    original = path.read_text().splitlines()
    cf = read_calibration(path)
    new = cf.calibration.with_offsets({"left_elbow_pitch": 0.123456789})
    write_calibration(path, CalibrationFile(new, cf.ids))
    updated = path.read_text().splitlines()
    assert len(updated) == len(original)
    changed = [(a, b) for a, b in zip(original, updated, strict=False) if a != b]
    assert changed == [("  homing_offset: -1.026153", "  homing_offset: 0.123456789")]
    assert (tmp_path / "calibration.yaml.bak").read_text().splitlines() == original


def test_ros2_transmission_updates_urdf_in_place(tmp_path: Path) -> None:
    path = tmp_path / "robot.urdf"
    shutil.copy(URDF, path)
    cf = read_calibration(EXAMPLES / "calibration.yaml")
    write_calibration(path, cf, "ros2-transmission")
    text = path.read_text()
    assert "<!-- left arm on can0 -->" in text
    assert text.count("<transmission ") == 14
    assert read_urdf(path).joint_names == read_urdf(URDF).joint_names
    back = read_calibration(path)
    assert back.calibration.is_close(cf.calibration, 0.0)
    assert back.ids["right_wrist_pitch"] == 27
    # second write with changed offsets edits the existing elements, does not add new ones
    write_calibration(path, CalibrationFile(cf.calibration.with_offsets({"left_wrist_roll": 0.25}), cf.ids))
    assert path.read_text().count("<transmission ") == 14
    assert read_calibration(path).calibration.joint_map("left_wrist_roll").homing_offset == 0.25


def test_transmission_with_gear_ratio_reads_scale(tmp_path: Path) -> None:
    path = tmp_path / "t.urdf"
    path.write_text(
        '<robot name="r"><transmission name="t"><type>transmission_interface/SimpleTransmission</type>'
        '<joint name="j"><hardwareInterface>x</hardwareInterface><offset>0.5</offset></joint>'
        '<actuator name="m"><mechanicalReduction>-10</mechanicalReduction></actuator></transmission></robot>'
    )
    cal = read_calibration(path).calibration
    jm = cal.joint_map("j")
    assert (jm.direction, jm.scale, jm.homing_offset) == (-1, 0.1, 5.0)
    raw = 3.0
    assert jm.to_joint(raw) == pytest.approx(raw / -10 + 0.5, abs=1e-15)


def test_detect_formats(tmp_path: Path) -> None:
    (tmp_path / "a.json").write_text('{"j": {"id": 1, "direction": 1, "homing_offset": 0.5}}')
    (tmp_path / "leg.json").write_text(
        json.dumps(
            {
                "homing_offset": [0],
                "drive_mode": [0],
                "start_pos": [0],
                "end_pos": [0],
                "calib_mode": ["DEGREE"],
                "motor_names": ["m"],
            }
        )
    )
    (tmp_path / "cur.json").write_text(
        json.dumps({"m": {"id": 1, "drive_mode": 0, "homing_offset": 0, "range_min": 0, "range_max": 4095}})
    )
    (tmp_path / "junk.txt").write_text("hello")
    assert detect_format(tmp_path / "a.json") == "lite-json"
    assert detect_format(EXAMPLES / "calibration.yaml") == "lite-yaml"
    assert detect_format(tmp_path / "leg.json") == "lerobot-legacy"
    with pytest.raises(FileFormatError, match="export-urdf"):
        detect_format(tmp_path / "cur.json")
    with pytest.raises(FileFormatError, match="unrecognised calibration format"):
        detect_format(tmp_path / "junk.txt")


def test_lite_formats_need_ids_and_rad(tmp_path: Path) -> None:
    cal = RobotCalibration(["a"], [1], [0.5])
    with pytest.raises(UsageError, match="needs a motor id for every joint; missing for a"):
        write_calibration(tmp_path / "x.json", cal)
    scaled = RobotCalibration(["a"], [1], [100.0], [math.pi / 2048])
    with pytest.raises(UsageError, match="use --to robocal"):
        write_calibration(tmp_path / "x.json", CalibrationFile(scaled, {"a": 1}))
    assert not (tmp_path / "x.json").exists()
    write_calibration(tmp_path / "x.yaml", CalibrationFile(scaled, {"a": 1}), "robocal")
    assert read_calibration(tmp_path / "x.yaml").calibration.is_close(scaled, 0.0)


def test_negative_zero_and_tiny_floats_written_safely(tmp_path: Path) -> None:
    cal = RobotCalibration(["a", "b"], [1, 1], [-0.0, 1e-20])
    write_calibration(tmp_path / "c.yaml", CalibrationFile(cal, {"a": 1, "b": 2}), "lite-yaml")
    text = (tmp_path / "c.yaml").read_text()
    assert "homing_offset: 0.0" in text
    assert "homing_offset: 1.0e-20" in text
    import yaml  # PyYAML (YAML 1.1) must also read the value as a float

    assert yaml.safe_load(text)["b"]["homing_offset"] == 1e-20


@settings(suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(
    cf=calibration_files(),
    scales=st.lists(st.floats(1e-6, 1e3, allow_nan=False), min_size=10, max_size=10),
)
def test_robocal_format_keeps_any_scale(tmp_path: Path, cf: CalibrationFile, scales: list[float]) -> None:
    cal = cf.calibration
    scaled = RobotCalibration(cal.joint_names, cal.direction, cal.homing_offset, scales[: cal.n_joints])
    path = tmp_path / "map.yaml"
    write_calibration(path, CalibrationFile(scaled, cf.ids), "robocal")
    back = read_calibration(path)
    assert back.calibration.is_close(scaled, 0.0)
    raw = np.linspace(-100, 100, cal.n_joints)
    np.testing.assert_array_equal(back.calibration.to_joint(raw), scaled.to_joint(raw))
