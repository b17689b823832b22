from __future__ import annotations

from pathlib import Path

import pytest
from hypothesis import given
from hypothesis import strategies as st

from robocal.errors import FileFormatError, JointMismatchError
from robocal.formats.urdf import UrdfDocument, parse_urdf, read_urdf

EXAMPLE = Path(__file__).resolve().parents[2] / "examples" / "lite" / "lite_bimanual.urdf"

SMALL = b"""<?xml version="1.0"?>
<!-- header comment -->
<robot name="two">
  <link name="base"/><link name="l1"/><link name="l2"/>
  <joint name="shoulder" type="revolute">
    <parent link="base"/><child link="l1"/>
    <origin xyz="0 0 0.1" rpy="0 0 0"/>
    <axis xyz="0 0 1"/>
    <limit lower="-1.57" upper="1.57" velocity="2" effort="10"/>
  </joint>
  <joint name="elbow" type="continuous">
    <parent link="l1"/><child link="l2"/>
    <!-- no origin -->
  </joint>
  <ros2_control name="Sys" type="system">
    <hardware><plugin>x/Y</plugin><param name="can_interface">can0</param></hardware>
    <joint name="shoulder">
      <command_interface name="position"><param name="min">-1</param></command_interface>
      <param name="can_id">1</param>
      <param name="direction">-1</param>
      <param name="homing_offset">0.1234</param>
    </joint>
  </ros2_control>
</robot>
"""


def test_reads_joints_limits_and_params() -> None:
    m = parse_urdf(SMALL, "small")
    # ros2_control <joint> entries are not robot joints
    assert m.joint_names == ("shoulder", "elbow")
    shoulder = m.joint("shoulder")
    assert (shoulder.lower, shoulder.upper, shoulder.velocity, shoulder.effort) == (
        -1.57,
        1.57,
        2.0,
        10.0,
    )
    assert shoulder.origin_xyz_m == (0.0, 0.0, 0.1) and shoulder.axis == (0.0, 0.0, 1.0)
    elbow = m.joint("elbow")  # no <limit>, no <origin>, no <axis>: URDF's defaults
    assert (elbow.lower, elbow.upper, elbow.velocity, elbow.effort) == (None, None, None, None)
    assert elbow.origin_xyz_m == (0.0, 0.0, 0.0) and elbow.axis == (1.0, 0.0, 0.0)
    # joint-level params only (the interface-level <param name="min"> is separate)
    assert dict(m.joint_params["shoulder"]) == {"can_id": "1", "direction": "-1", "homing_offset": "0.1234"}
    assert dict(m.hardware_params["Sys"]) == {"can_interface": "can0"}
    assert (m.direction("shoulder"), m.motor_id("shoulder")) == (-1, 1)
    assert m.calibration_joint_names() == ("shoulder",)
    with pytest.raises(JointMismatchError, match="no joint 'knee'; joints: shoulder, elbow"):
        m.joint("knee")
    with pytest.raises(FileFormatError, match="joint 'elbow': has no lower/upper limit"):
        m.limits("elbow")


def test_lite_example_table() -> None:
    m = read_urdf(EXAMPLE)
    assert len(m.calibration_joint_names()) == 14
    assert m.limits("left_shoulder_pitch") == (-3.142, 0.785)
    assert m.limits("right_shoulder_roll") == (-1.92, 1.571)
    assert [m.motor_id(n) for n in m.calibration_joint_names()] == [*range(11, 18), *range(21, 28)]
    assert m.direction("right_elbow_pitch") == 1 and m.direction("left_elbow_pitch") == -1


def test_unchanged_document_round_trips_byte_for_byte() -> None:
    assert UrdfDocument.from_bytes(SMALL).to_bytes() == SMALL
    assert UrdfDocument.load(EXAMPLE).to_bytes() == EXAMPLE.read_bytes()


def test_edits_in_place_keep_everything_else(tmp_path: Path) -> None:
    doc = UrdfDocument.from_bytes(SMALL)
    doc.set_origin("shoulder", (0.0, -0.0, 0.1), (0.0, 0.0, 1.5707963267948966))
    doc.set_origin("elbow", (0.5, 0, 0), (0, 0, 0))  # creates <origin>
    doc.set_param("shoulder", "homing_offset", "0.5")
    doc.set_param("shoulder", "model", "rs-02")  # appended
    path = tmp_path / "out.urdf"
    doc.write(path)
    text = path.read_text()
    assert "<!-- header comment -->" in text and "<!-- no origin -->" in text
    assert '<origin xyz="0 0 0.1" rpy="0 0 1.5707963267948966"/>' in text  # unchanged numbers keep their text
    m = read_urdf(path)
    assert m.joint("elbow").origin_xyz_m == (0.5, 0.0, 0.0)
    assert dict(m.joint_params["shoulder"]) == {
        "can_id": "1",
        "direction": "-1",
        "homing_offset": "0.5",
        "model": "rs-02",
    }
    assert text.count("<ros2_control") == 1
    with pytest.raises(JointMismatchError, match="not in any <ros2_control> block"):
        doc.set_param("elbow", "direction", "1")


@given(st.lists(st.floats(-10, 10, allow_nan=False), min_size=6, max_size=6))
def test_origin_write_read_identical(values: list[float]) -> None:
    doc = UrdfDocument.from_bytes(SMALL)
    doc.set_origin("shoulder", values[:3], values[3:])
    j = parse_urdf(doc.to_bytes()).joint("shoulder")
    assert list(j.origin_xyz_m) == [v + 0.0 for v in values[:3]]
    assert list(j.origin_rpy_rad) == [v + 0.0 for v in values[3:]]
    assert " -0.0 " not in doc.to_bytes().decode().replace('"', " ")


def test_xacro_is_refused_with_a_hint() -> None:
    xacro = b'<robot name="r" xmlns:xacro="http://www.ros.org/wiki/xacro"><xacro:property name="a" value="1"/></robot>'
    with pytest.raises(FileFormatError, match=r"xacro robot\.urdf\.xacro > robot\.urdf"):
        parse_urdf(xacro)
    with pytest.raises(FileFormatError, match="xacro"):
        parse_urdf(b'<robot name="r"><link name="${prefix}base"/></robot>')
    assert (
        parse_urdf(b'<robot name="r"><!-- made from ${robot}.xacro --><link name="a"/></robot>').name == "r"
    )
