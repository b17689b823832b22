"""Regression tests from the review of the LeRobot area: edge inputs of the public API, paths, CLI outputs."""

from __future__ import annotations

import json
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest

from robocal.backends.dynamixel import DynamixelBus
from robocal.backends.feetech import FeetechBus
from robocal.backends.sim.servo import SimServo, SimServoBus
from robocal.cli.main import main
from robocal.errors import FileFormatError, InvalidCalibrationError, UsageError
from robocal.formats.lerobot import LEGACY_KEYS
from robocal.lerobot import MotorCalibration, calibration_path, legacy, normalize, unnormalize
from robocal.workflows.lerobot import robot_spec

pytestmark = pytest.mark.timeout(60)

CAL = MotorCalibration(id=1, drive_mode=0, homing_offset=0, range_min=1000, range_max=3000)
LEGACY = (
    '{"homing_offset": [2048, 3072, 3072, -1024, -1024, 2048], "drive_mode": [1, 1, 1, 0, 0, 0], '
    '"start_pos": [2015, 3058, 3061, 1071, 1071, 2499], "end_pos": [-1008, -1963, -1966, 2141, 2143, 3144], '
    '"calib_mode": ["DEGREE", "DEGREE", "DEGREE", "DEGREE", "DEGREE", "LINEAR"], '
    '"motor_names": ["shoulder_pan", "shoulder_lift", "elbow_flex", "wrist_flex", "wrist_roll", "gripper"]}'
)


# ------------------------------------------------------------------------------------------ public API edges
def test_scalar_raw_with_a_one_motor_sequence() -> None:
    out = normalize(1500, [CAL], "range_m100_100")
    assert out.shape == () and float(out) == -50.0
    back = unnormalize(-50.0, [CAL], ["range_m100_100"])
    assert back.shape == () and int(back) == 1500
    one = legacy.LegacyCalibration(["a"], [0], [0], [0], [0], ["DEGREE"])
    deg = legacy.apply_calibration(1024, one)
    assert isinstance(deg, np.ndarray) and deg.shape == () and float(deg) == 90.0
    ticks = legacy.revert_calibration(90.0, one)
    assert isinstance(ticks, np.ndarray) and ticks.shape == () and int(ticks) == 1024


def test_calibration_mapping_is_taken_in_order() -> None:
    cals = {"a": CAL, "b": MotorCalibration(2, 1, 0, 1000, 3000)}
    np.testing.assert_array_equal(normalize([1500, 1500], cals, "range_m100_100"), [-50.0, 50.0])


@pytest.mark.parametrize("mode", [None, 2, 2.0, b"degrees", [None]])
def test_bad_mode_types_are_calib_errors(mode: object) -> None:
    with pytest.raises(InvalidCalibrationError, match="norm mode"):
        normalize(1500, CAL, mode)  # type: ignore[arg-type]
    with pytest.raises(InvalidCalibrationError, match="norm mode"):
        unnormalize(0.0, CAL, mode)  # type: ignore[arg-type]


@pytest.mark.parametrize("raw", ["abc", 1 + 2j, [[1, 2], [3]], {"a": 1}])
def test_non_numeric_raw_is_a_calib_error(raw: object) -> None:
    with pytest.raises(InvalidCalibrationError, match="raw"):
        normalize(raw, CAL, "degrees")  # type: ignore[arg-type]
    with pytest.raises(InvalidCalibrationError, match="values"):
        unnormalize(raw, CAL, "degrees")  # type: ignore[arg-type]


@pytest.mark.parametrize("compat", ["lerobot", "exact"])
def test_unnormalize_beyond_int64_raises_instead_of_wrapping(compat: str) -> None:
    with pytest.raises(InvalidCalibrationError, match="int64"):
        unnormalize(1e300, CAL, "degrees", compat=compat)  # type: ignore[arg-type]
    assert int(unnormalize(1e300, CAL, "range_m100_100", compat=compat)) == 3000  # clamped: fine  # type: ignore[arg-type]
    one = legacy.LegacyCalibration(["a"], [0], [0], [0], [0], ["DEGREE"])
    with pytest.raises(InvalidCalibrationError, match="int64"):
        legacy.revert_calibration([1e300], one)


@pytest.mark.parametrize("resolution", [0, 1, -4096])
def test_bad_resolution_is_refused(resolution: int) -> None:
    with pytest.raises(InvalidCalibrationError, match="resolution"):
        normalize(1500, CAL, "degrees", resolution=resolution)
    with pytest.raises(InvalidCalibrationError, match="resolution"):
        unnormalize(0.0, CAL, "degrees", resolution=resolution)


def test_legacy_file_without_motors_is_refused(tmp_path: Path) -> None:
    p = tmp_path / "empty.json"
    p.write_text(json.dumps({k: [] for k in LEGACY_KEYS}))
    with pytest.raises(FileFormatError, match="no motors"):
        legacy.read_legacy(p)


# ------------------------------------------------------------------------------------------------- paths
def test_calibration_root_follows_huggingface_hub(monkeypatch: pytest.MonkeyPatch, tmp_path: Path) -> None:
    for var in ("HF_LEROBOT_CALIBRATION", "HF_LEROBOT_HOME", "HF_HOME"):
        monkeypatch.delenv(var, raising=False)
    monkeypatch.setenv("HOME", str(tmp_path))
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "xdg"))
    # huggingface_hub: HF_HOME defaults to $XDG_CACHE_HOME/huggingface
    assert calibration_path("robots", "so_follower", "a") == (
        tmp_path / "xdg/huggingface/lerobot/calibration/robots/so_follower/a.json"
    )
    monkeypatch.setenv("HF_HOME", "~/hf")
    assert calibration_path("robots", "so_follower", "a") == (
        tmp_path / "hf/lerobot/calibration/robots/so_follower/a.json"
    )


# ------------------------------------------------------------------------------------------------- buses
@pytest.fixture
def buses() -> Iterator[tuple[FeetechBus, DynamixelBus]]:
    with (
        SimServoBus([SimServo(1, "sts3215", 1337.0)]) as fsim,
        SimServoBus([SimServo(1, "xl330-m288", 1337.0)]) as dsim,
    ):
        fb = FeetechBus(fsim.port, {1: "sts3215"}, retries=0)
        db = DynamixelBus(dsim.port, {1: "xl330-m288"}, retries=0)
        try:
            yield fb, db
        finally:
            fb.close()
            db.close()


def test_sync_write_checks_the_register_width(buses: tuple[FeetechBus, DynamixelBus]) -> None:
    fb, db = buses
    with pytest.raises(UsageError, match="does not fit register 'Lock'"):
        fb.sync_write("Lock", {1: 256})
    with pytest.raises(UsageError, match="does not fit register 'Drive_Mode'"):
        db.sync_write("Drive_Mode", {1: 300})
    assert fb.ping(1) == 777 and db.ping(1) == 1200  # nothing was sent; the buses still work


def test_empty_sync_calls_are_usage_errors(buses: tuple[FeetechBus, DynamixelBus]) -> None:
    for bus in buses:
        with pytest.raises(UsageError, match="no motor ids"):
            bus.sync_read("Present_Position", [])
        with pytest.raises(UsageError, match="no motor ids"):
            bus.sync_write("Goal_Position", {})


# --------------------------------------------------------------------------------------------------- CLI
def _run(args: list[str], capsys: pytest.CaptureFixture[str]) -> tuple[int, list[str], str]:
    code = main(args)
    cap = capsys.readouterr()
    return code, cap.err.strip().splitlines(), cap.out


def test_calibrate_into_a_file_as_folder_is_one_error_line_and_no_bus_io(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    blocker = tmp_path / "blocker"
    blocker.write_text("x")
    args = ["lerobot", "calibrate", "--robot", "so101_follower", "--port", "sim", "--id", "a"]
    code, err, _ = _run([*args, "--calibration-dir", str(blocker)], capsys)
    assert code == 2
    assert len([e for e in err if e.startswith("error:")]) == 1
    assert err[-1].startswith(f"error: cannot write {blocker}/robots/so_follower/a.json")
    assert not any(e.startswith("reading") for e in err)  # refused before the sweep
    (tmp_path / "cal/robots/so_follower/b.json").mkdir(parents=True)
    code, err, _ = _run([*args[:-1], "b", "--calibration-dir", str(tmp_path / "cal")], capsys)
    assert code == 2 and err[-1].endswith("is a directory")
    assert not any(e.startswith("reading") for e in err)
    assert blocker.read_text() == "x"


def test_migrate_out_under_a_file_is_one_error_line(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    src = tmp_path / "legacy.json"
    src.write_text(LEGACY)
    blocker = tmp_path / "blocker"
    blocker.write_text("x")
    code, err, _ = _run(
        ["lerobot", "migrate", str(src), "--vendor", "dynamixel", "--out", str(blocker / "x.json")], capsys
    )
    assert code == 2
    assert err == [f"error: cannot write {blocker}/x.json: {blocker} is not a folder"]


@pytest.mark.parametrize(
    ("ids", "message"),
    [
        ("1,1,2,3,4,5", "error: --ids: motor id 1 is given twice"),
        ("1,2,3,4,5,300", "error: --ids: motor id 300 is outside 0..253"),
        ("1,2,3,4,5,-1", "error: --ids: motor id -1 is outside 0..253"),
    ],
)
def test_migrate_refuses_bad_ids_even_when_printing(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], ids: str, message: str
) -> None:
    src = tmp_path / "legacy.json"
    src.write_text(LEGACY)
    code, err, out = _run(["lerobot", "migrate", str(src), "--vendor", "dynamixel", "--ids", ids], capsys)
    assert code == 2
    assert err == [message]
    assert out == ""


# ---------------------------------------------------------------------------------------- restore / check
@pytest.mark.parametrize(
    ("robot", "motor", "field", "value", "message"),
    [
        ("so101_follower", "wrist_roll", "homing_offset", 5000, "Magnitude 5000 exceeds 2047"),
        ("so101_follower", "gripper", "range_max", 70000, "value 70000 does not fit register"),
        ("koch_leader", "gripper", "range_min", -5, "value -5 does not fit register 'Min_Position_Limit'"),
    ],
)
def test_restore_validates_every_value_before_writing_any(
    robot: str, motor: str, field: str, value: int, message: str
) -> None:
    from dataclasses import replace

    from robocal.backends.sim.lerobot_arms import SimArm
    from robocal.errors import CalibError
    from robocal.workflows.lerobot import open_bus, restore

    with SimArm(robot_spec(robot)) as arm:
        cals = {m.name: MotorCalibration(m.motor_id, 0, 7, 100, 4000) for m in arm.spec.motors}
        cals[motor] = replace(cals[motor], **{field: value})
        before = arm.eeprom()
        torque = {m.name: arm.servo(m.name).get_reg("Torque_Enable") for m in arm.spec.motors}
        bus = open_bus(arm.spec, arm.port)
        try:
            with pytest.raises(CalibError, match=message):
                restore(bus, arm.spec, cals)
        finally:
            bus.close()
        assert arm.eeprom() == before
        assert {m.name: arm.servo(m.name).get_reg("Torque_Enable") for m in arm.spec.motors} == torque


# --------------------------------------------------------------------------------------- writers, extras
def test_writers_refuse_wrong_types_with_calib_errors(tmp_path: Path) -> None:
    from robocal.lerobot import write_calibration

    with pytest.raises(InvalidCalibrationError, match="motor 'a': expected a MotorCalibration"):
        write_calibration(tmp_path / "w.json", {"a": {"id": 1}})  # type: ignore[dict-item]
    with pytest.raises(InvalidCalibrationError, match="expected a mapping of motor name"):
        write_calibration(tmp_path / "w.json", [CAL])  # type: ignore[arg-type]
    with pytest.raises(InvalidCalibrationError, match="expected a LegacyCalibration"):
        legacy.write_legacy(tmp_path / "l.json", {"homing_offset": [0]})  # type: ignore[arg-type]
    assert list(tmp_path.iterdir()) == []


def test_convert_degrees_to_steps_truncates_like_lerobot() -> None:
    out = legacy.convert_degrees_to_steps([0, 90, 180, -90, 45.5, -45.5])
    assert out.tolist() == [0, 1024, 2048, -1024, 517, -517]


@pytest.mark.parametrize(("module", "extra"), [("scservo_sdk", "feetech"), ("dynamixel_sdk", "dynamixel")])
def test_missing_sdk_names_the_extra(monkeypatch: pytest.MonkeyPatch, module: str, extra: str) -> None:
    import sys

    from robocal.errors import BackendNotAvailableError

    monkeypatch.setitem(sys.modules, module, None)
    bus_cls = FeetechBus if extra == "feetech" else DynamixelBus
    with pytest.raises(BackendNotAvailableError, match=rf"pip install 'robocal\[{extra}\]'"):
        bus_cls("/dev/null", {1: "sts3215" if extra == "feetech" else "xl330-m288"})
