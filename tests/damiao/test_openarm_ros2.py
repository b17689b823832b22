"""The ROS 2 side of an OpenArm session: ``openarm-ros2`` (ros2_control ``joint_limits`` parameters with the
measured ranges), bytes pinned, read as a third party reads it (ruamel.yaml), and ``convert`` between it,
``openarm-lerobot`` and ``robocal`` keeping the measured ranges (round trips byte-exact where the format allows)."""

from __future__ import annotations

import math
from pathlib import Path

import pytest
from ruamel.yaml import YAML

from robocal.cli.main import main
from robocal.core.jointmap import RobotCalibration
from robocal.errors import FileFormatError, InvalidCalibrationError
from robocal.formats import detect_format, read_calibration, write_calibration
from robocal.formats.calibration._base import CalibrationFile
from robocal.formats.calibration.openarm_ros2 import finger_m, gripper_rad
from robocal.formats.urdf import read_urdf

from .openarm_session import RIGHT, URDF, openarm_session, session_file

MEASURED = {  # a session's ranges, rad: J4 0.1..139.9°, the gripper −59.7..−0.2°
    RIGHT[3]: (math.radians(0.1), math.radians(139.9)),
    RIGHT[7]: (math.radians(-59.7), math.radians(-0.2)),
}
PINNED_J4 = (
    "  openarm_right_joint4:\n    has_position_limits: true\n    min_position: 0.001746\n"
    "    max_position: 2.441715\n"
)
PINNED_FINGER = (
    "  openarm_right_finger_joint1:\n    has_position_limits: true\n    min_position: 0.000147\n"
    "    max_position: 0.043779\n"
)


def _cal(offset_deg: float = 0.0) -> CalibrationFile:
    return session_file(offset_deg, MEASURED)


def _write(path: Path, cf: CalibrationFile, fmt: str) -> None:
    write_calibration(path, cf, fmt, urdf=read_urdf(URDF), robot="openarm_follower_right")


def test_gripper_mapping_is_openarm_ros2s() -> None:
    # v10_simple_hardware: motor 0 rad = finger 0 m (closed), motor -1.0472 rad = 0.044 m (open), linear
    assert finger_m(0.0) == 0.0 and finger_m(-1.0472) == pytest.approx(0.044, abs=1e-15)
    assert gripper_rad(0.022) == pytest.approx(-0.5236, abs=1e-12)


def test_bytes_pinned_and_read_by_ruamel_as_ros_would(tmp_path: Path) -> None:
    out = tmp_path / "joint_limits.yaml"
    _write(out, _cal(), "openarm-ros2")
    text = out.read_text()
    assert PINNED_J4 in text and text.endswith(PINNED_FINGER)
    doc = YAML(typ="safe").load(text)  # what a ROS 2 launch file / MoveIt loads
    limits = doc["joint_limits"]
    assert list(limits) == [f"openarm_right_joint{i}" for i in range(1, 8)] + ["openarm_right_finger_joint1"]
    for name, entry in limits.items():
        assert entry["has_position_limits"] is True and entry["min_position"] < entry["max_position"], name
        assert set(entry) == {"has_position_limits", "min_position", "max_position"}
    # measured ranges, inward to six decimals; the others the URDF's limits (J1 -80..200°)
    assert limits["openarm_right_joint4"]["min_position"] == 0.001746
    assert limits["openarm_right_joint1"] == {"has_position_limits": True, "min_position": -1.396263,
                                              "max_position": 3.490659}
    assert math.radians(0.1) <= limits["openarm_right_joint4"]["min_position"] < math.radians(0.1) + 1e-6
    assert detect_format(out) == "openarm-ros2"
    cf = read_calibration(out, urdf=read_urdf(URDF))
    assert cf.calibration.joint_names == tuple(RIGHT) and list(cf.calibration.homing_offset) == [0.0] * 8
    lo, hi = cf.ranges_rad[RIGHT[7]]  # inward by up to 1 µm of finger travel: 0.0014° of the motor
    assert math.degrees(lo) == pytest.approx(-59.7, abs=0.002) and math.degrees(hi) == pytest.approx(-0.2, abs=0.002)


def test_refuses_offsets_and_joints_without_a_range(tmp_path: Path) -> None:
    out = tmp_path / "joint_limits.yaml"
    with pytest.raises(InvalidCalibrationError, match=r"openarm_right_joint1 \(\+0\.100°\).*--write-zero"):
        _write(out, _cal(0.1), "openarm-ros2")
    cal = RobotCalibration(["elbow"], [1], [0.0])
    with pytest.raises(InvalidCalibrationError, match="needs a range for joint elbow"):
        write_calibration(out, CalibrationFile(cal), "openarm-ros2")
    assert not out.exists()


def test_node_parameter_file_reads_and_bad_entries_name_the_joint(tmp_path: Path) -> None:
    p = tmp_path / "params.yaml"
    p.write_text(
        "controller_manager:\n  ros__parameters:\n    joint_limits:\n      openarm_left_joint3:\n"
        "        has_position_limits: true\n        min_position: -1.5\n        max_position: 1.5\n"
        "      openarm_left_finger_joint1:\n        has_velocity_limits: true\n        max_velocity: 10.0\n"
    )
    assert detect_format(p) == "openarm-ros2"
    cf = read_calibration(p)
    assert cf.calibration.joint_names == ("openarm_left_joint3",) and cf.ranges_rad["openarm_left_joint3"] == (-1.5, 1.5)
    p.write_text("joint_limits:\n  j1:\n    has_position_limits: true\n    min_position: 1.0\n    max_position: 0.5\n")
    with pytest.raises(FileFormatError, match=r"joint 'j1': min_position 1.0 is not below max_position 0.5"):
        read_calibration(p, "openarm-ros2")
    p.write_text("joint_limits:\n  j1:\n    min_position: 0.0\n    max_position: 0.5\n")
    with pytest.raises(FileFormatError, match=r"joint 'j1': min_position/max_position need has_position_limits"):
        read_calibration(p, "openarm-ros2")


def test_convert_keeps_the_measured_ranges_both_ways(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    u = ["--urdf", str(URDF)]
    lr, ros, rc = tmp_path / "arm.json", tmp_path / "joint_limits.yaml", tmp_path / "cal.yaml"
    _write(lr, _cal(), "openarm-lerobot")
    _write(ros, _cal(), "openarm-ros2")
    # robocal keeps full precision: ros2 -> robocal -> ros2 and lerobot -> robocal -> lerobot are byte-exact
    for src, fmt in ((ros, "openarm-ros2"), (lr, "openarm-lerobot")):
        assert main(["convert", str(src), str(rc), "--to", "robocal", *u]) == 0
        back = tmp_path / f"back-{src.name}"
        assert main(["convert", str(rc), str(back), "--to", fmt, *u]) == 0
        assert back.read_bytes() == src.read_bytes(), fmt
        rc.unlink()
    # LeRobot's whole degrees go to ROS 2 and come back unchanged (lerobot -> ros2 -> lerobot byte-exact)
    via = tmp_path / "via.yaml"
    assert main(["convert", str(lr), str(via), "--to", "openarm-ros2", *u]) == 0
    again = tmp_path / "again.json"
    assert main(["convert", str(via), str(again), "--to", "openarm-lerobot", *u]) == 0
    assert again.read_bytes() == lr.read_bytes()
    # the ROS file of LeRobot's J4 1..139° holds exactly those degrees (six decimals, inward)
    j4 = YAML(typ="safe").load(via.read_text())["joint_limits"]["openarm_right_joint4"]
    assert (j4["min_position"], j4["max_position"]) == (0.017454, 2.426007)
    assert main(["check", "--calibration", str(ros), *u]) == 0
    out = capsys.readouterr().out
    assert "8/8 joints matched (openarm-ros2)" in out and "robot profile: openarm_follower_right" in out


@pytest.mark.slow
def test_one_session_writes_the_ros_file_with_the_measured_ranges(tmp_path: Path) -> None:
    from robocal.workflows.autocal.sweep import SweepAutoRequest

    out = tmp_path / "joint_limits.yaml"
    request = SweepAutoRequest(URDF, "sim:openarm?seed=4", out, robot="openarm_follower_right", fmt="openarm-ros2",
                               joints=(RIGHT[4], RIGHT[7]), write_zero=True)
    with openarm_session(request) as (outcome, sim):
        arm = sim.arm
        truth = {n: (j.stop_lower_rad, j.stop_upper_rad) for n, j in zip(RIGHT, arm.joints, strict=True)}
        assert all(abs(math.degrees(arm.zero_error_rad(m))) < 0.1 for m in ("joint_5", "gripper"))
    assert outcome.out == out and outcome.exit_code == 0
    limits = YAML(typ="safe").load(out.read_text())["joint_limits"]
    assert list(limits) == ["openarm_right_joint5", "openarm_right_finger_joint1"]
    j5 = limits["openarm_right_joint5"]  # the measured range, within 0.5° of the simulated stops
    assert math.degrees(abs(j5["min_position"] - truth[RIGHT[4]][0])) < 0.5
    assert math.degrees(abs(j5["max_position"] - truth[RIGHT[4]][1])) < 0.5
    finger = limits["openarm_right_finger_joint1"]
    assert abs(gripper_rad(finger["max_position"]) - truth[RIGHT[7]][0]) < math.radians(0.5)
    assert abs(gripper_rad(finger["min_position"]) - truth[RIGHT[7]][1]) < math.radians(0.5)
