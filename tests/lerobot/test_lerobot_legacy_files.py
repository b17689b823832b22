"""robocal.formats.lerobot: legacy files, writers, LeRobot's calibration folders; legacy degrees → steps."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from robocal.errors import FileFormatError, InvalidCalibrationError
from robocal.formats.lerobot import LEGACY_KEYS
from robocal.lerobot import MotorCalibration, calibration_path, legacy

pytestmark = pytest.mark.timeout(60)

CAL = MotorCalibration(id=1, drive_mode=0, homing_offset=0, range_min=1000, range_max=3000)


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
