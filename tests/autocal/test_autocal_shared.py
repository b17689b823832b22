"""Small rules the auto-calibration modules share: the Feetech mid-turn offset, saving a LeRobot calibration,
the simulated faults of ``sim:lite`` and ``--port sim?…``."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from robocal.backends.feetech.joint_driver import mid_turn_offset
from robocal.core.lerobot import MotorCalibration
from robocal.workflows.autocal.sim import SIM_FAULTS, fault_scenario
from robocal.workflows.lerobot.calibrate import CalibrationNotSavedError, save_calibration


@pytest.mark.parametrize(
    ("actual", "offset"),
    [(2047, 0), (0, -2047), (4095, 2047), (3000, 953), (100, -1947), (1000, -1047)],
)
def test_mid_turn_offset_puts_the_joint_mid_turn_within_the_register(actual: int, offset: int) -> None:
    assert mid_turn_offset(actual, 4096) == offset
    assert (actual - offset) % 4096 == 2047 or abs(offset) == 2047  # Present = (Actual − offset) mod res


def test_mid_turn_offset_for_another_resolution() -> None:
    assert mid_turn_offset(0, 1024) == -511
    assert mid_turn_offset(600, 1024) == 89


def test_save_calibration_writes_lerobot_json_or_nothing_without_a_path(tmp_path: Path) -> None:
    cals = {"shoulder_pan": MotorCalibration(1, 0, 12, 800, 3000)}
    assert save_calibration(None, cals) is None
    written = save_calibration(tmp_path / "a.json", cals)
    assert written == tmp_path / "a.json"
    assert json.loads(written.read_text())["shoulder_pan"] == {
        "id": 1,
        "drive_mode": 0,
        "homing_offset": 12,
        "range_min": 800,
        "range_max": 3000,
    }


def test_save_calibration_failure_keeps_the_calibration(tmp_path: Path) -> None:
    blocker = tmp_path / "file"
    blocker.write_text("x")
    cals = {"gripper": MotorCalibration(6, 0, 0, 2000, 3000)}
    with pytest.raises(CalibrationNotSavedError) as info:
        save_calibration(blocker / "a.json", cals)
    assert info.value.calibration == cals
    assert str(info.value).startswith(f"cannot write {blocker}/a.json")
    assert blocker.read_text() == "x"


def test_fault_scenario_maps_each_sim_fault_to_its_scenario_field() -> None:
    faults = {k: set() for k in SIM_FAULTS} | {"missing": {"a"}, "stiction": {"a", "b"}, "silent": {"b"}}
    a, b, c = (fault_scenario(n, faults) for n in "abc")
    assert (a.missing_stop, a.stiction_ratio, a.silent_at_stop) == ("upper", 0.8, False)
    assert (b.missing_stop, b.stiction_ratio, b.silent_at_stop) == ("none", 0.8, True)
    assert not (c.soft_stop or c.obstacle or c.cable_snag or c.overload_latch or c.silent_at_stop)
    assert (c.missing_stop, c.stiction_ratio) == ("none", 0.0)
    for fault, field in [("soft", "soft_stop"), ("obstacle", "obstacle"), ("snag", "cable_snag"),
                         ("overload", "overload_latch")]:  # fmt: skip
        assert getattr(fault_scenario("j", {k: set() for k in SIM_FAULTS} | {fault: {"j"}}), field) is True
