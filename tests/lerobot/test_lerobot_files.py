"""LeRobot calibration files (current and legacy), paths and the legacy joint-map conversion."""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st
from tests.robots import SO101_JOINTS

from robocal.errors import FileFormatError, InvalidCalibrationError, JointOutOfRangeError, UsageError
from robocal.lerobot import MotorCalibration, calibration_path, legacy, read_calibration, write_calibration

SO101_TEXT = """{
    "shoulder_pan": {
        "id": 1,
        "drive_mode": 0,
        "homing_offset": -1849,
        "range_min": 1021,
        "range_max": 3058
    },
    "wrist_roll": {
        "id": 5,
        "drive_mode": 0,
        "homing_offset": -710,
        "range_min": 0,
        "range_max": 4095
    }
}"""

ALOHA_LEFT_FOLLOWER = (
    '{"homing_offset": [2048, 3072, 3072, -1024, -1024, 2048, -2048, 2048, -2048], '
    '"drive_mode": [1, 1, 1, 0, 0, 1, 0, 1, 0], '
    '"start_pos": [2015, 3058, 3061, 1071, 1071, 2035, 2152, 2029, 2499], '
    '"end_pos": [-1008, -1963, -1966, 2141, 2143, -971, 3043, -1077, 3144], '
    '"calib_mode": ["DEGREE", "DEGREE", "DEGREE", "DEGREE", "DEGREE", "DEGREE", "DEGREE", "DEGREE", '
    '"LINEAR"], '
    '"motor_names": ["waist", "shoulder", "shoulder_shadow", "elbow", "elbow_shadow", "forearm_roll", '
    '"wrist_angle", "wrist_rotate", "gripper"]}'
)


def test_current_file_round_trip_is_byte_identical(tmp_path: Path) -> None:
    src = tmp_path / "in.json"
    src.write_text(SO101_TEXT)
    cals = read_calibration(src)
    assert list(cals) == ["shoulder_pan", "wrist_roll"]
    assert cals["shoulder_pan"] == MotorCalibration(1, 0, -1849, 1021, 3058)
    out = tmp_path / "sub" / "out.json"
    write_calibration(out, cals)
    assert out.read_text() == SO101_TEXT


@given(
    st.lists(
        st.tuples(st.integers(0, 1), st.integers(-2047, 2047), st.integers(0, 2000), st.integers(1, 2095)),
        min_size=1,
        max_size=8,
    )
)
def test_current_round_trip_property(rows: list[tuple[int, int, int, int]]) -> None:
    from robocal.formats.lerobot import dumps_current, parse_current

    cals = {f"m{i}": MotorCalibration(i + 1, dm, h, lo, lo + w) for i, (dm, h, lo, w) in enumerate(rows)}
    assert parse_current(dumps_current(cals)) == cals


@pytest.mark.parametrize(
    ("mutate", "message"),
    [
        (
            lambda d: d["shoulder_pan"].pop("range_max"),
            "motor 'shoulder_pan': missing required field(s) range_max",
        ),
        (lambda d: d["wrist_roll"].update(extra=1), "motor 'wrist_roll': unknown field(s) extra"),
        (
            lambda d: d["wrist_roll"].update(range_min=1.5),
            "motor 'wrist_roll': field range_min is 1.5; expected an integer",
        ),
        (
            lambda d: d["wrist_roll"].update(id="5"),
            "motor 'wrist_roll': field id is '5'; expected an integer",
        ),
        (lambda d: d["wrist_roll"].update(drive_mode=2), "field drive_mode is 2; expected 0 or 1"),
        (
            lambda d: d["wrist_roll"].update(range_min=4095),
            "field range_min 4095 must be less than range_max 4095",
        ),
        (lambda d: d["wrist_roll"].update(id=1), "field id 1 is also used by 'shoulder_pan'"),
        (
            lambda d: d["wrist_roll"].update(homing_offset=True),
            "field homing_offset is True; expected an integer",
        ),
    ],
)
def test_current_malformed_matrix(tmp_path: Path, mutate, message: str) -> None:  # type: ignore[no-untyped-def]
    _refused_after(mutate, SO101_TEXT, tmp_path / "bad.json", read_calibration, message)


def _refused_after(mutate: Any, text: str, path: Path, read: Any, message: str) -> None:
    """``read`` refuses the JSON ``text`` changed by ``mutate`` and written to ``path``, naming ``path``."""
    data = json.loads(text)
    mutate(data)
    path.write_text(json.dumps(data))
    with pytest.raises(FileFormatError) as exc:
        read(path)
    assert str(path) in str(exc.value) and message in str(exc.value)


@pytest.mark.parametrize(
    ("text", "message"),
    [
        ("{", "invalid JSON"),
        ("[1, 2]", "expected a JSON object of motors, got list"),
        ("{}", "no motors"),
        (ALOHA_LEFT_FOLLOWER, "legacy LeRobot calibration"),
        ('{"a": 3}', "motor 'a': expected an object, got int"),
        ('{"a": {"id": 1}, "a": {"id": 2}}', "duplicate key 'a'"),
    ],
)
def test_current_malformed_text(tmp_path: Path, text: str, message: str) -> None:
    bad = tmp_path / "bad.json"
    bad.write_text(text)
    with pytest.raises(FileFormatError, match=message):
        read_calibration(bad)


def test_missing_file_is_file_format_error(tmp_path: Path) -> None:
    with pytest.raises(FileFormatError, match="no such file"):
        read_calibration(tmp_path / "nope.json")


def test_calibration_path(monkeypatch: pytest.MonkeyPatch, tmp_path: Path) -> None:
    for var in ("HF_LEROBOT_CALIBRATION", "HF_LEROBOT_HOME", "HF_HOME", "XDG_CACHE_HOME"):
        monkeypatch.delenv(var, raising=False)
    monkeypatch.setenv("HOME", str(tmp_path))
    assert calibration_path("robots", "so_follower", "arm1") == (
        tmp_path / ".cache/huggingface/lerobot/calibration/robots/so_follower/arm1.json"
    )
    monkeypatch.setenv("HF_HOME", "/hf")
    assert calibration_path("teleoperator", "so_leader", None) == Path(
        "/hf/lerobot/calibration/teleoperators/so_leader/None.json"
    )
    monkeypatch.setenv("HF_LEROBOT_HOME", "/lh")
    assert calibration_path("robots", "koch_follower", "k") == Path(
        "/lh/calibration/robots/koch_follower/k.json"
    )
    monkeypatch.setenv("HF_LEROBOT_CALIBRATION", "/cal")
    assert calibration_path("robots", "so101_follower", "x") == Path("/cal/robots/so101_follower/x.json")
    assert calibration_path("robots", "so_follower", "x", root="/r") == Path("/r/robots/so_follower/x.json")
    with pytest.raises(UsageError, match="calibration kind 'robot_arms'"):
        calibration_path("robot_arms", "so_follower", "x")
    with pytest.raises(UsageError, match=r"calibration id '\.\./x'"):
        calibration_path("robots", "so_follower", "../x")


# ------------------------------------------------------------------------------------------------- legacy
def test_legacy_file_round_trip_is_byte_identical(tmp_path: Path) -> None:
    src = tmp_path / "left_follower.json"
    src.write_text(ALOHA_LEFT_FOLLOWER)
    cal = legacy.read_legacy(src)
    assert cal.motor_names[0] == "waist" and cal.end_pos[0] == -1008 and cal.calib_mode[-1] == "LINEAR"
    out = tmp_path / "copy.json"
    legacy.write_legacy(out, cal)
    assert out.read_text() == ALOHA_LEFT_FOLLOWER
    # waist: rotated 1008 < zero 2015 -> dm 1 -> homing 1024 - round(-1008/1024)*1024 = 2048
    rebuilt = legacy.calibration_from_poses(["waist"], [2015], [1008], vendor="dynamixel")
    assert rebuilt.homing_offset.tolist() == [2048] and rebuilt.end_pos.tolist() == [-1008]


def test_legacy_apply_revert_on_file(tmp_path: Path) -> None:
    src = tmp_path / "f.json"
    src.write_text(ALOHA_LEFT_FOLLOWER)
    cal = legacy.read_legacy(src)
    raw = np.array([[2015, 3058, 3061, 1071, 1071, 2035, 2152, 2029, 2499]] * 2)
    deg = legacy.apply_calibration(raw, cal)
    assert deg.shape == (2, 9) and deg[0, 8] == 0.0
    assert deg[0, 0] == pytest.approx((-2015 + 2048) / 2048 * 180)
    assert legacy.revert_calibration(deg, cal).tolist() == raw.tolist()
    with pytest.raises(JointOutOfRangeError, match="detected for gripper"):
        legacy.apply_calibration(raw[0] + np.array([0] * 8 + [-500]), cal)


def test_so100_issue_930_file_and_shoulder_lift_reconstruction(tmp_path: Path) -> None:
    text = json.dumps(
        {
            "homing_offset": [-2145, 4, -1401, -3126, 2970, -1769],
            "drive_mode": [0, 1, 0, 0, 1, 0],
            "start_pos": [2085, 56, 1285, 3237, 3080, 1983],
            "end_pos": [3169, 1020, 2425, 4150, -1946, 2793],
            "calib_mode": ["DEGREE"] * 5 + ["LINEAR"],
            "motor_names": list(SO101_JOINTS),
        }
    )
    p = tmp_path / "main_follower.json"
    p.write_text(text)
    cal = legacy.read_legacy(p)
    # raw 3076 unwrapped to -1020 by avoid_rotation_reset: drive mode 1, negated 1020, homing 1024 - 1020 = 4
    from robocal.core.lerobot import avoid_rotation_reset

    unwrapped = int(avoid_rotation_reset(np.array([56, 3076]))[-1])
    assert unwrapped == -1020
    fe = legacy.calibration_from_poses(["shoulder_lift"], [56], [unwrapped], vendor="feetech")
    assert fe.drive_mode.tolist() == [1] and fe.homing_offset.tolist() == [cal.homing_offset[1]] == [4]


@pytest.mark.parametrize(
    ("mutate", "message"),
    [
        (lambda d: d.pop("end_pos"), "missing key(s) end_pos"),
        (lambda d: d.update(version=2), "unknown key(s) version"),
        (lambda d: d["start_pos"].pop(), "key start_pos has 8 entries; expected 9"),
        (lambda d: d["calib_mode"].__setitem__(0, "ANGLE"), "calib_mode[0] is 'ANGLE'"),
        (lambda d: d["drive_mode"].__setitem__(2, 3), "drive_mode[2] is 3; expected 0 or 1"),
        (lambda d: d["homing_offset"].__setitem__(1, 1.5), "homing_offset[1] is 1.5; expected an integer"),
        (lambda d: d.update(motor_names="waist"), "key motor_names is str; expected a list"),
        (lambda d: d["motor_names"].__setitem__(1, "waist"), "duplicate motor names"),
    ],
)
def test_legacy_malformed_matrix(tmp_path: Path, mutate, message: str) -> None:  # type: ignore[no-untyped-def]
    _refused_after(mutate, ALOHA_LEFT_FOLLOWER, tmp_path / "legacy.json", legacy.read_legacy, message)


def test_legacy_reader_rejects_current_file(tmp_path: Path) -> None:
    p = tmp_path / "c.json"
    p.write_text(SO101_TEXT)
    with pytest.raises(FileFormatError, match="current LeRobot calibration"):
        legacy.read_legacy(p)


def test_to_robot_calibration_is_exact() -> None:
    cal = legacy.LegacyCalibration(
        ["a", "b", "c"], [2048, -1024, 0], [1, 0, 0], [0, 0, 0], [1, 1, 1], ["DEGREE"] * 3
    )
    rc = legacy.to_robot_calibration(cal)
    assert rc.joint_names == ("a", "b", "c")
    assert rc.direction.tolist() == [-1.0, 1.0, 1.0]
    assert rc.homing_offset.tolist() == [2048.0, 1024.0, 0.0]
    assert rc.scale.tolist() == [math.pi / 2048] * 3
    raw = np.array([[2048, 1024, 0], [1024, 2048, 1024], [0, 4096, 2047]])
    np.testing.assert_allclose(rc.to_joint(raw), np.deg2rad(legacy.apply_calibration(raw, cal)), atol=1e-12)
    np.testing.assert_allclose(rc.to_raw(rc.to_joint(raw)), raw, atol=1e-9)


def test_to_robot_calibration_names_every_linear_joint(tmp_path: Path) -> None:
    cal = legacy.LegacyCalibration(
        ["a", "grip1", "grip2"], [0, 0, 0], [0, 0, 0], [0, 0, 0], [1, 1, 1], ["DEGREE", "LINEAR", "LINEAR"]
    )
    with pytest.raises(InvalidCalibrationError, match="LINEAR motor\\(s\\) grip1, grip2 are not convertible"):
        legacy.to_robot_calibration(cal)
