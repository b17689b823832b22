"""A signal while the calibration file is being written no longer undoes the motors (found by the fault soak).

Before: SIGTERM right after ``lerobot calibrate --auto`` wrote its file made the guard write the previous EEPROM
back and say "no file was written" — the file held the new calibration, the motors the old one. Now the last step
holds signals off (``MotionGuard.finish_with``); the signal then ends the command (exit 143) with one line naming
the file written, and the motors hold what the file says. Judged by the simulated servos' registers.
"""

from __future__ import annotations

import json
import os
import signal
from pathlib import Path
from typing import Any

import pytest

import robocal.workflows.lerobot.auto as auto_mod
from robocal.backends.sim.lerobot_arms import SimArm
from robocal.cli.main import main

pytestmark = pytest.mark.timeout(600)


@pytest.mark.slow
def test_sigterm_while_the_file_is_written_keeps_file_and_motors_agreeing(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    real_save = auto_mod.save_calibration

    def save_then_sigterm(path: Any, cals: Any) -> Any:
        out = real_save(path, cals)
        os.kill(os.getpid(), signal.SIGTERM)  # lands while the write step holds signals off
        return out

    monkeypatch.setattr(auto_mod, "save_calibration", save_then_sigterm)
    eeproms: list[dict[str, dict[str, int]]] = []
    real_stop = SimArm.stop

    def stop(self: SimArm) -> None:
        eeproms.append(self.eeprom())  # the servos as the command left them
        real_stop(self)

    monkeypatch.setattr(SimArm, "stop", stop)
    args = ["lerobot", "calibrate", "--auto", "--yes", "--robot", "so101_follower", "--port", "sim", "--id", "w",
            "--calibration-dir", str(tmp_path), "--joints", "gripper"]  # fmt: skip
    code = main(args)
    err = capsys.readouterr().err
    assert code == 143, err
    (path,) = tmp_path.rglob("w.json")
    lines = [x for x in err.splitlines() if x.strip()]
    assert lines[-1] == f"interrupted by SIGTERM after writing {path} (complete)", err
    assert "no file was written" not in err and "error:" not in err, err
    written = json.loads(path.read_text())
    (servos,) = eeproms
    for motor, cal in written.items():  # the motors hold what the file says
        assert servos[motor]["Homing_Offset"] == cal["homing_offset"], motor
        assert servos[motor]["Min_Position_Limit"] == cal["range_min"], motor
        assert servos[motor]["Max_Position_Limit"] == cal["range_max"], motor


def test_finish_with_holds_a_signal_until_the_write_is_done_then_raises_it_without_restoring() -> None:
    """``MotionGuard.finish_with``: a SIGTERM during the last write is held, the write completes, nothing is
    restored (the motors keep what the file says) and the signal then ends the run (exit 143)."""
    from robocal.errors import SignalInterrupt
    from robocal.workflows.motion.guard import MotionGuard

    calls: list[str] = []

    def limp() -> list[str]:
        calls.append("limp")
        return []

    def restore(snapshot: Any) -> Any:
        calls.append("restore")
        raise AssertionError("a finished write must not be undone")

    def write() -> str:
        os.kill(os.getpid(), signal.SIGTERM)  # arrives inside the write
        calls.append("written")
        return "file"

    with pytest.raises(SignalInterrupt) as caught, MotionGuard(limp=limp, restore=restore) as guard:
        guard.snapshot({"gripper": {"Homing_Offset": 5}})
        guard.finish_with(write)
    assert caught.value.exit_code == 143
    assert calls[0] == "written" and "restore" not in calls
