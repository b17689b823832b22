"""formats/calibration.py on real-world file variants and edge inputs (found by the foundation audit)."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from robocal.cli.main import main
from robocal.core.jointmap import RobotCalibration
from robocal.errors import FileFormatError, InvalidCalibrationError, JointMismatchError, ShapeMismatchError
from robocal.formats import CalibrationFile, read_calibration, write_calibration
from robocal.formats.urdf import parse_urdf, read_urdf
from robocal.workflows.files.job import check_calibration

EXAMPLES = Path(__file__).resolve().parents[2] / "examples" / "lite"
LITE_URDF = EXAMPLES / "lite_bimanual.urdf"

# one transmission at the top level (ROS 1 style: <type>, reduction on the actuator), one inside <ros2_control>
MIXED_URDF = """<?xml version="1.0"?>
<robot name="mixed">
  <link name="base"/><link name="l1"/><link name="l2"/><link name="l3"/>
  <joint name="ns/j1" type="revolute"><parent link="base"/><child link="l1"/>
    <limit lower="-1" upper="1" effort="1" velocity="1"/></joint>
  <joint name="j2" type="continuous"><parent link="l1"/><child link="l2"/></joint>
  <joint name="j3" type="revolute"><parent link="l2"/><child link="l3"/>
    <limit lower="-1" upper="1" effort="1" velocity="1"/><mimic joint="j2"/></joint>
  <ros2_control name="A" type="system">
    <hardware><plugin>x</plugin></hardware>
    <joint name="ns/j1"><param name="can_id">1</param><param name="direction">-1</param></joint>
    <joint name="j2"><param name="can_id">2</param><param name="direction">1</param></joint>
    <transmission name="t2">
      <plugin>transmission_interface/SimpleTransmission</plugin>
      <joint name="j2" role="joint1"><mechanical_reduction>1</mechanical_reduction></joint>
    </transmission>
  </ros2_control>
  <transmission name="t1">
    <type>transmission_interface/SimpleTransmission</type>
    <joint name="ns/j1"><hardwareInterface>PositionJointInterface</hardwareInterface></joint>
    <actuator name="m1"><mechanicalReduction>-1</mechanicalReduction></actuator>
  </transmission>
</robot>
"""


def test_robot_calibration_refuses_boolean_arrays() -> None:
    with pytest.raises(InvalidCalibrationError, match="direction holds booleans"):
        RobotCalibration(["a"], [True], [0.0])
    with pytest.raises(InvalidCalibrationError, match="homing_offset holds booleans"):
        RobotCalibration(["a"], [1], [True])
    with pytest.raises(InvalidCalibrationError, match="one string"):
        RobotCalibration("ab", [1, 1], [0.0, 0.0])


def test_direction_spellings_are_accepted() -> None:
    cal = RobotCalibration(["a", "b", "c"], [-1.0, "1", np.int64(-1)], [0, 1, 2])
    assert cal.direction.tolist() == [-1.0, 1.0, -1.0]
    assert cal.homing_offset.tolist() == [0.0, 1.0, 2.0]


def test_zero_joint_calibration_maps_empty_arrays() -> None:
    cal = RobotCalibration([], [], [])
    raw = np.zeros((100_000, 0))
    out = np.empty_like(raw)
    assert cal.to_joint(raw, out=out) is out  # was ZeroDivisionError
    assert cal.to_raw(np.zeros((3, 0))).shape == (3, 0)


def test_non_numeric_input_is_a_shape_error() -> None:
    cal = RobotCalibration(["a", "b"], [1, -1], [0.5, 1.0])
    with pytest.raises(
        ShapeMismatchError, match=r"raw position is not a numeric array of shape \(\.\.\., 2\)"
    ):
        cal.to_joint([[1.0, 2.0], [3.0]])
    with pytest.raises(ShapeMismatchError, match="joint velocity is not a numeric array"):
        cal.velocity_to_raw("ab")
    with pytest.raises(ShapeMismatchError, match="out is a list"):
        cal.to_joint([1.0, 2.0], out=[0.0, 0.0])  # type: ignore[arg-type]
    with pytest.raises(InvalidCalibrationError, match="period must be finite"):
        cal.unwrap_to_limits([0.0, 0.0], -1.0, 1.0, float("nan"))


def test_berkeley_written_with_urdf_is_in_urdf_order(tmp_path: Path) -> None:
    lite = read_calibration(EXAMPLES / "calibration.yaml")
    reversed_names = list(reversed(lite.calibration.joint_names))
    src = tmp_path / "rev.json"
    write_calibration(src, CalibrationFile(lite.calibration.select(reversed_names), lite.ids), "lite-json")
    dst = tmp_path / "offsets.yaml"
    assert main(["convert", str(src), str(dst), "--to", "berkeley-offsets", "--urdf", str(LITE_URDF)]) == 0
    back = read_calibration(dst, urdf=read_urdf(LITE_URDF))
    assert back.calibration.is_close(lite.calibration, atol=0.0)  # was: offsets silently on the wrong joints


def test_berkeley_write_with_urdf_refuses_other_joints(tmp_path: Path) -> None:
    cal = RobotCalibration(["left_elbow_pitch", "nope"], [-1, 1], [0.1, 0.2])
    with pytest.raises(JointMismatchError, match=r"not in robot bhl_arms: nope\).*pass --joints"):
        write_calibration(tmp_path / "b.yaml", cal, "berkeley-offsets", urdf=read_urdf(LITE_URDF))
    assert not (tmp_path / "b.yaml").exists()


def test_lite_yaml_update_writes_exactly_the_calibration(tmp_path: Path) -> None:
    dst = tmp_path / "calibration.yaml"
    dst.write_text((EXAMPLES / "calibration.yaml").read_text())
    cal = RobotCalibration(["left_elbow_pitch"], [-1], [0.25])
    write_calibration(dst, CalibrationFile(cal, {"left_elbow_pitch": 14}), "lite-yaml")
    back = read_calibration(dst)
    assert back.calibration.is_close(cal, atol=0.0)  # the 13 other joints were left behind
    assert dict(back.ids) == {"left_elbow_pitch": 14}
    assert dst.read_text().startswith("# Lite bimanual joint zero offsets")


def test_detection_reports_syntax_errors(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    tabs = tmp_path / "c.yaml"
    tabs.write_text("a:\n\tid: 1\n")
    broken = tmp_path / "c.json"
    broken.write_text('{"a": {"id": 1, "direction": 1, "homing_offset": 0.5}')
    assert main(["convert", str(tabs), str(tmp_path / "x.json")]) == 2
    assert "invalid YAML (line 2, column 1)" in capsys.readouterr().err
    assert main(["convert", str(broken), str(tmp_path / "x.yaml")]) == 2
    assert "invalid JSON (line 1" in capsys.readouterr().err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["c.json", "c.yaml"]


def test_transmissions_read_in_document_order_ros1_and_ros2(tmp_path: Path) -> None:
    urdf = tmp_path / "r.urdf"
    urdf.write_text(MIXED_URDF)
    cf = read_calibration(urdf)
    assert cf.fmt == "ros2-transmission"
    assert cf.calibration.joint_names == ("j2", "ns/j1")  # document order, not top-level first
    assert cf.calibration.direction.tolist() == [1.0, -1.0]
    assert dict(cf.ids) == {"j2": 2, "ns/j1": 1}


def test_transmission_rewrite_of_unchanged_values_is_byte_identical(tmp_path: Path) -> None:
    urdf = tmp_path / "r.urdf"
    urdf.write_text(MIXED_URDF)
    cf = read_calibration(urdf)
    write_calibration(urdf, cf, "ros2-transmission")
    assert urdf.read_text() == MIXED_URDF  # the ROS 1 actuator reduction was duplicated onto the joint


def test_transmission_update_of_ros1_reduction_stays_on_the_actuator(tmp_path: Path) -> None:
    urdf = tmp_path / "r.urdf"
    urdf.write_text(MIXED_URDF)
    cal = RobotCalibration(["ns/j1"], [1], [0.0])
    write_calibration(urdf, cal, "ros2-transmission")
    text = urdf.read_text()
    assert "<mechanicalReduction>1.0</mechanicalReduction>" in text
    assert text.count("mechanical_reduction>") == 2  # only j2's element, no new one on ns/j1
    assert read_calibration(urdf).calibration.select(["ns/j1"]).is_close(cal, atol=0.0)


def test_check_warns_on_transmission_direction_disagreement(tmp_path: Path) -> None:
    urdf = tmp_path / "r.urdf"
    urdf.write_text(
        MIXED_URDF.replace('<param name="direction">1</param>', '<param name="direction">-1</param>')
    )
    model = read_urdf(urdf)
    report = check_calibration(read_calibration(urdf), model)
    assert report.warnings == (
        "j2: direction +1 in the file disagrees with -1 in the URDF (the robot uses the URDF's)",
    )


def test_check_warns_on_robocal_direction_disagreement(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    lite = read_calibration(EXAMPLES / "calibration.yaml")
    flipped = lite.calibration.with_directions({"left_elbow_pitch": 1})
    dst = tmp_path / "map.yaml"
    write_calibration(dst, CalibrationFile(flipped, lite.ids), "robocal")
    assert main(["check", "--calibration", str(dst), "--urdf", str(LITE_URDF)]) == 1
    err = capsys.readouterr().err
    assert "warning: left_elbow_pitch: direction +1 in the file disagrees with -1 in the URDF" in err


def test_mimic_joints_are_not_calibration_joints() -> None:
    text = MIXED_URDF.split("<ros2_control")[0] + "</robot>\n"
    model = parse_urdf(text)
    assert model.movable_joint_names == ("ns/j1", "j2", "j3")
    assert model.calibration_joint_names() == ("ns/j1", "j2")


def test_decimal_ids_with_leading_zero() -> None:
    model = parse_urdf(
        MIXED_URDF.replace('<param name="can_id">1</param>', '<param name="can_id">011</param>')
    )
    assert model.motor_id("ns/j1") == 11
    assert parse_urdf(MIXED_URDF.replace(">2</param>", ">0x1B</param>")).motor_id("j2") == 27


def test_variant_files_convert_exactly(tmp_path: Path) -> None:
    # PyYAML block list, a JSON file with integer offsets and string directions, BOM + CRLF
    urdf = read_urdf(LITE_URDF)
    order = ["left_shoulder_pitch", "left_elbow_pitch"]
    block = tmp_path / "offsets.yaml"
    block.write_text("position_offsets:\n- 0.1\n- -2\n")
    cf = read_calibration(block, joint_order=order, urdf=urdf)
    assert cf.calibration.homing_offset.tolist() == [-0.1, 2.0]
    ints = tmp_path / "ints.json"
    ints.write_text(
        json.dumps(
            {
                "a": {"id": 1, "direction": "-1", "homing_offset": 0},
                "b": {"id": 2, "direction": 1, "homing_offset": 3},
            }
        )
    )
    assert read_calibration(ints).calibration.homing_offset.tolist() == [0.0, 3.0]
    bom = tmp_path / "bom.yaml"
    bom.write_bytes("\ufeffa:\r\n  id: 1\r\n  direction: -1\r\n  homing_offset: 0.5\r\n".encode())
    assert read_calibration(bom).calibration.is_close(RobotCalibration(["a"], [-1], [0.5]), atol=0.0)


def test_anchors_aliases_and_merge_keys_are_refused(tmp_path: Path) -> None:
    """Issue 9 (they were read before): an alias makes two entries one shared object, which an update in place
    changes together, and a merge key hides which values a joint has. Anchors, aliases and merge keys are
    refused at their line and column, in this reader as in every other YAML reader."""
    anchors = tmp_path / "anchors.yaml"
    anchors.write_text("a: &x {id: 1, direction: -1, homing_offset: 0.5}\nb:\n  <<: *x\n  id: 2\n")
    with pytest.raises(
        FileFormatError, match=r"anchors\.yaml: invalid YAML \(line 1, column 4\): an anchor \(&x\)"
    ):
        read_calibration(anchors)
    merge = tmp_path / "merge.yaml"
    merge.write_text("a:\n  <<: {id: 1, direction: -1}\n  homing_offset: 0.5\n")
    with pytest.raises(
        FileFormatError, match=r"merge\.yaml: invalid YAML \(line 2, column 3\): a merge key \(<<\)"
    ):
        read_calibration(merge)
    out = tmp_path / "out.yaml"
    out.write_text("a: &x {id: 1, direction: -1, homing_offset: 0.5}\nb: *x\n")
    before = out.read_bytes()
    cal = RobotCalibration(["a", "b"], [-1, -1], [0.25, 0.75])
    with pytest.raises(FileFormatError, match=r"exists but is not a lite-yaml calibration file .*an anchor"):
        write_calibration(out, CalibrationFile(cal, ids={"a": 1, "b": 2}), "lite-yaml")
    assert out.read_bytes() == before
