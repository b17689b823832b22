"""Issue 15 (Lite): the official URDFs and an upstream position_offsets file through check and convert."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from lite_testutil import (
    BIMANUAL_URDF,
    BIPED_URDF,
    FULL_URDF,
    UPSTREAM_CAL,
    UPSTREAM_DIRS,
    UPSTREAM_IDS,
    URDF_ORDER,
)
from ruamel.yaml import YAML

from robocal.cli.main import main
from robocal.core import RobotCalibration
from robocal.errors import JointMismatchError
from robocal.formats import CalibrationFile, read_calibration, write_calibration
from robocal.formats.profiles import load_profile
from robocal.formats.urdf import read_urdf


def _upstream_offsets() -> list[float]:
    return [float(v) for v in YAML(typ="safe").load(UPSTREAM_CAL.read_text())["position_offsets"]]


def test_official_urdfs_have_no_direction_params() -> None:
    for path in (BIPED_URDF, FULL_URDF):
        urdf = read_urdf(path)
        assert urdf.joint_params == {} and all(urdf.direction(n) is None for n in urdf.joint_names)
    # document order is not the low-level code's order: ankle_roll comes first
    assert read_urdf(BIPED_URDF).calibration_joint_names()[0] == "leg_left_ankle_roll_joint"


@pytest.mark.parametrize("urdf", [BIPED_URDF, FULL_URDF])
def test_check_upstream_file_with_official_urdf_is_12_of_12(
    urdf: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    rc = main(["check", "--calibration", str(UPSTREAM_CAL), "--urdf", str(urdf)])
    out = capsys.readouterr()
    assert rc == 0, out.err
    assert f"{UPSTREAM_CAL}: 12/12 joints matched (berkeley-offsets)" in out.out
    assert "robot profile: bhl_biped (recognised from the URDF's joint names)" in out.out
    assert out.err == ""


def test_convert_upstream_file_to_lite_yaml_and_back(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    lite = tmp_path / "calibration_lite.yaml"
    assert (
        main(["convert", str(UPSTREAM_CAL), str(lite), "--to", "lite-yaml", "--urdf", str(BIPED_URDF)]) == 0
    )
    data = YAML(typ="safe").load(lite.read_text())
    offs = _upstream_offsets()
    assert list(data) == URDF_ORDER
    assert [data[n]["id"] for n in URDF_ORDER] == UPSTREAM_IDS
    assert [data[n]["direction"] for n in URDF_ORDER] == UPSTREAM_DIRS
    # homing_offset = direction * offset, exactly
    assert [data[n]["homing_offset"] for n in URDF_ORDER] == [
        d * o for d, o in zip(UPSTREAM_DIRS, offs, strict=True)
    ]
    back = tmp_path / "calibration.yaml"
    assert main(["convert", str(lite), str(back), "--to", "berkeley-offsets", "--urdf", str(BIPED_URDF)]) == 0
    assert YAML(typ="safe").load(back.read_text())["position_offsets"] == offs  # upstream order, bit-exact
    assert "robot profile: bhl_biped" in capsys.readouterr().out


def test_berkeley_is_never_written_in_urdf_document_order(tmp_path: Path) -> None:
    """Defect 2: a calibration in URDF document order is written in the low-level code's order."""
    urdf = read_urdf(BIPED_URDF)
    doc = list(urdf.calibration_joint_names())
    p = load_profile("bhl_biped")
    cal = RobotCalibration(doc, [p.direction(n) for n in doc], np.arange(12) / 10.0)  # type: ignore[misc]
    out = tmp_path / "calibration.yaml"
    write_calibration(out, cal, "berkeley-offsets", urdf=urdf)
    offs = YAML(typ="safe").load(out.read_text())["position_offsets"]
    expected = [p.direction(n) * cal.joint_map(n).homing_offset for n in URDF_ORDER]  # type: ignore[operator]
    assert offs == expected
    assert offs[0] == -0.5  # left_hip_roll (document index 5, direction -1), not ankle_roll


def test_berkeley_without_profile_needs_joints(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    src = tmp_path / "c.json"
    src.write_text(json.dumps({"a": {"id": 1, "direction": 1, "homing_offset": 0.5},
                               "b": {"id": 2, "direction": -1, "homing_offset": 0.25}}))  # fmt: skip
    dst = tmp_path / "b.yaml"
    assert main(["convert", str(src), str(dst), "--to", "berkeley-offsets"]) == 2
    err = capsys.readouterr().err
    assert (
        err.count("error:") == 1 and "positional" in err and "pass --joints" in err and "--robot NAME" in err
    )
    assert "URDF's document order" in err and not dst.exists()
    assert main(["convert", str(src), str(dst), "--to", "berkeley-offsets", "--joints", "b,a"]) == 0
    assert "position_offsets: [-0.25, 0.5]" in dst.read_text()
    # read back: with --joints, and without (the file names its order)
    for extra in (["--joints", "b,a"], []):
        back = tmp_path / "back.json"
        assert (
            main(["convert", str(dst), str(back), "--to", "robocal", *extra, "--from", "berkeley-offsets"])
            == 2
        )
        assert "needs each joint's direction" in capsys.readouterr().err  # no URDF, no profile: no directions


def test_berkeley_written_is_read_back(tmp_path: Path) -> None:
    """Defect 3: every berkeley-offsets file robocal writes reads back (same URDF, or --joints)."""
    urdf = read_urdf(BIPED_URDF)
    cf = read_calibration(UPSTREAM_CAL, urdf=urdf)
    out = tmp_path / "b.yaml"
    write_calibration(out, cf, "berkeley-offsets", urdf=urdf)
    assert read_calibration(out, urdf=urdf).calibration.is_close(cf.calibration, 0.0)
    # order from the file, robot recognised from its joint names
    assert read_calibration(out).calibration.is_close(cf.calibration, 0.0)
    order = list(reversed(URDF_ORDER))
    write_calibration(out, cf, "berkeley-offsets", urdf=urdf, joint_order=order)
    back = read_calibration(out, urdf=urdf, joint_order=order)
    assert back.calibration.joint_names == tuple(order)
    assert back.calibration.is_close(cf.calibration.select(order), 0.0)
    # with the URDF alone, the order the file names wins over the profile's (its offsets stay on their joints),
    # with a note: the robot's code would read it in its own order
    alone = read_calibration(out, urdf=urdf)
    assert alone.calibration.is_close(cf.calibration.select(order), 0.0)
    assert "another order than robot bhl_biped's low-level code reads" in alone.notes[0]
    with pytest.raises(
        JointMismatchError, match="the file says its joint order is leg_right_ankle_roll_joint"
    ):
        read_calibration(out, urdf=urdf, joint_order=URDF_ORDER)  # --joints contradicting the file


def test_upstream_names_accepted_for_joints(tmp_path: Path) -> None:
    lite, out = tmp_path / "lite.yaml", tmp_path / "x.yaml"
    assert main(["convert", str(UPSTREAM_CAL), str(lite), "--to", "lite-yaml", "--robot", "bhl_biped"]) == 0
    assert main(["convert", str(lite), str(out), "--to", "robocal", "--robot", "bhl_biped",
                 "--joints", "left_knee_pitch_joint,right_knee_pitch_joint"]) == 0  # fmt: skip
    back = read_calibration(out)
    assert back.calibration.joint_names == ("leg_left_knee_pitch_joint", "leg_right_knee_pitch_joint")
    assert back.calibration.homing_offset.tolist() == [-_upstream_offsets()[3], _upstream_offsets()[9]]


def test_pass_urdf_not_suggested_when_urdf_was_passed(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """Defect 7: the missing-id message does not say '(pass --urdf)' when --urdf was given."""
    urdf = tmp_path / "r.urdf"
    urdf.write_text(BIPED_URDF.read_text().replace("leg_left_knee_pitch_joint", "knee"))  # no profile matches
    src = tmp_path / "c.json"
    src.write_text(json.dumps({"knee": {"direction": 1, "homing_offset": 0.5}}))
    dst = tmp_path / "c.yaml"
    assert main(["convert", str(src), str(dst), "--to", "lite-yaml", "--urdf", str(urdf)]) == 2
    err = capsys.readouterr().err
    assert "needs a motor id for every joint; missing for knee" in err
    assert "(pass --urdf)" not in err and f"URDF {urdf} has no id/can_id param for them" in err
    assert main(["convert", str(src), str(dst), "--to", "lite-yaml"]) == 2
    assert "pass --urdf with id/can_id params, or --robot NAME" in capsys.readouterr().err


def test_check_names_joint_and_both_sources_on_direction_disagreement(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    cf = read_calibration(UPSTREAM_CAL, urdf=read_urdf(BIPED_URDF))
    cal = cf.calibration.with_directions({"leg_right_knee_pitch_joint": -1})
    lite = tmp_path / "c.yaml"
    write_calibration(lite, CalibrationFile(cal, cf.ids), "lite-yaml")
    urdf = tmp_path / "r.urdf"  # a URDF with a <ros2_control> direction param for one joint
    text = BIPED_URDF.read_text().replace(
        "</robot>",
        '<ros2_control name="s" type="system"><joint name="leg_left_hip_yaw_joint">'
        '<param name="direction">-1</param></joint></ros2_control>\n</robot>',
    )
    urdf.write_text(text)
    rc = main(["check", "--calibration", str(lite), "--urdf", str(BIPED_URDF)])
    err = capsys.readouterr().err
    assert rc == 1
    assert (
        "leg_right_knee_pitch_joint: direction -1 in the file disagrees with +1 in profile bhl_biped" in err
    )
    rc = main(["check", "--calibration", str(lite), "--urdf", str(urdf), "--robot", "bhl_biped"])
    err = capsys.readouterr().err
    assert rc == 1
    assert "leg_left_hip_yaw_joint: direction +1 in the file disagrees with -1 in the URDF" in err
    assert "leg_left_hip_yaw_joint: direction -1 in the URDF disagrees with +1 in profile bhl_biped" in err


# ----------------------------------------------------------------------------------------- round trips
WRITABLE = ("lite-json", "lite-yaml", "berkeley-offsets", "ros2-transmission", "robocal")
PROFILES = {"bhl_biped": BIPED_URDF, "bhl_arms": BIMANUAL_URDF}


@settings(suppress_health_check=[HealthCheck.function_scoped_fixture], max_examples=40)
@given(
    robot=st.sampled_from(sorted(PROFILES)),
    first=st.sampled_from(WRITABLE),
    second=st.sampled_from(WRITABLE),
    offsets=st.lists(st.floats(-3.0, 3.0, allow_nan=False), min_size=14, max_size=14),
    shuffle=st.randoms(use_true_random=False),
)
def test_every_format_pair_round_trips(
    tmp_path: Path, robot: str, first: str, second: str, offsets: list[float], shuffle: object
) -> None:
    profile = load_profile(robot)
    urdf = read_urdf(PROFILES[robot])
    names = list(profile.joint_names)
    shuffle.shuffle(names)  # type: ignore[attr-defined]
    cal = RobotCalibration(names, [profile.direction(n) for n in names], offsets[: len(names)])  # type: ignore[misc]
    a, b = tmp_path / f"a.{first}", tmp_path / f"b.{second}"
    for p in (a, b):
        p.unlink(missing_ok=True)
    write_calibration(a, cal, first, urdf=urdf)
    mid = read_calibration(a, first, urdf=urdf)
    write_calibration(b, mid, second, urdf=urdf)
    back = read_calibration(b, second, urdf=urdf).calibration
    assert sorted(back.joint_names) == sorted(names)
    assert back.select(names).is_close(cal, 0.0)  # same directions, bit-identical offsets


def test_check_warns_when_file_order_is_not_the_codes_order(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "b.yaml"
    cf = read_calibration(UPSTREAM_CAL, robot="bhl_biped")
    write_calibration(out, cf, "berkeley-offsets", joint_order=list(reversed(URDF_ORDER)))
    rc = main(["check", "--calibration", str(out), "--urdf", str(BIPED_URDF)])
    captured = capsys.readouterr()
    assert rc == 1 and "12/12 joints matched" in captured.out
    assert "another order than robot bhl_biped's low-level code reads them" in captured.err


def test_check_full_humanoid_names_joints_the_code_does_not_drive(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    cf = read_calibration(UPSTREAM_CAL, robot="bhl_biped")
    arm = RobotCalibration(["arm_left_elbow_pitch_joint"], [1], [0.5])
    both = RobotCalibration(
        [*cf.calibration.joint_names, *arm.joint_names],
        [*cf.calibration.direction, 1],
        [*cf.calibration.homing_offset, 0.5],
    )
    lite = tmp_path / "c.yaml"
    write_calibration(lite, CalibrationFile(both, {**cf.ids, "arm_left_elbow_pitch_joint": 9}), "lite-yaml")
    rc = main(["check", "--calibration", str(lite), "--urdf", str(FULL_URDF)])
    out = capsys.readouterr()
    assert rc == 1 and "12/12 joints matched (lite-yaml)" in out.out
    assert "robot bhl_biped's code does not drive (or the URDF lacks): arm_left_elbow_pitch_joint" in out.err
