"""The OpenArm's files from one session: LeRobot's openarm_follower JSON (bytes pinned), the zero stored in the
motors (judged by the simulator's truth), convert / check through the format registry."""

from __future__ import annotations

import json
import math
from pathlib import Path

import pytest

from robocal.cli.main import main
from robocal.errors import FileFormatError, InvalidCalibrationError
from robocal.formats import detect_format, read_calibration, write_calibration
from robocal.formats.calibration._base import CalibrationFile
from robocal.formats.urdf import read_urdf

from .openarm_session import RIGHT, URDF, openarm_session, session_file

# LeRobot 0.6.1 writes draccus.dump(..., indent=4): this is the text of a right arm with its design ranges
# (robocal's URDF limits, whole degrees) and J4 measured 0.1..139.9° (rounded inward: 1..139)
PINNED_HEAD = (
    '{\n    "joint_1": {\n        "id": 1,\n        "drive_mode": 0,\n        "homing_offset": 0,\n'
    '        "range_min": -80,\n        "range_max": 200\n    },\n    "joint_2": {\n        "id": 2,\n'
)
PINNED_J4 = (
    '    "joint_4": {\n        "id": 4,\n        "drive_mode": 0,\n        "homing_offset": 0,\n'
    '        "range_min": 1,\n        "range_max": 139\n    },\n'
)
PINNED_TAIL = (
    '    "gripper": {\n        "id": 8,\n        "drive_mode": 0,\n        "homing_offset": 0,\n'
    '        "range_min": -60,\n        "range_max": 0\n    }\n}'
)


def _cal(offsets_deg: float = 0.0) -> CalibrationFile:
    return session_file(offsets_deg, {RIGHT[3]: (math.radians(0.1), math.radians(139.9))})


def test_lerobot_json_bytes_sniffed_and_read_back(tmp_path: Path) -> None:
    out = tmp_path / "openarm.json"
    write_calibration(out, _cal(), "openarm-lerobot", urdf=read_urdf(URDF), robot="openarm_follower_right")
    text = out.read_text()
    assert text.startswith(PINNED_HEAD) and PINNED_J4 in text and text.endswith(PINNED_TAIL)
    assert list(json.loads(text)) == ["joint_1", "joint_2", "joint_3", "joint_4", "joint_5", "joint_6", "joint_7",
                                      "gripper"]
    assert detect_format(out) == "openarm-lerobot"
    cf = read_calibration(out, urdf=read_urdf(URDF))
    assert cf.calibration.joint_names == tuple(RIGHT)
    assert list(cf.calibration.homing_offset) == [0.0] * 8 and dict(cf.ids) == {n: i + 1 for i, n in enumerate(RIGHT)}
    assert cf.ranges_rad[RIGHT[3]] == (math.radians(1), math.radians(139))


def test_lerobot_json_refuses_offsets_it_cannot_hold(tmp_path: Path) -> None:
    out = tmp_path / "openarm.json"
    with pytest.raises(InvalidCalibrationError, match=r"openarm_right_joint1 \(\+0\.100°\).*--write-zero"):
        write_calibration(out, _cal(0.1), "openarm-lerobot", urdf=read_urdf(URDF), robot="openarm_follower_right")
    assert not out.exists()
    doc = {m: {"id": i, "drive_mode": 0, "homing_offset": 0, "range_min": -90, "range_max": 90}
           for i, m in enumerate(["joint_1", "joint_2", "joint_3", "joint_4", "joint_5", "joint_6", "joint_7",
                                  "gripper"], start=1)}
    doc["joint_3"]["homing_offset"] = 5
    p = tmp_path / "lr.json"
    p.write_text(json.dumps(doc, indent=4))
    with pytest.raises(FileFormatError, match=r"motor joint_3: drive_mode 0, homing_offset 5"):
        read_calibration(p, urdf=read_urdf(URDF))


def test_convert_and_check_between_robocal_and_lerobot(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    lr = tmp_path / "openarm.json"
    write_calibration(lr, _cal(), "openarm-lerobot", urdf=read_urdf(URDF), robot="openarm_follower_right")
    rc = tmp_path / "cal.yaml"
    assert main(["convert", str(lr), str(rc), "--to", "robocal", "--urdf", str(URDF)]) == 0
    back = tmp_path / "back.json"
    assert main(["convert", str(rc), str(back), "--to", "openarm-lerobot", "--urdf", str(URDF)]) == 0
    # the robocal format keeps the measured ranges (J4 1..139, not the URDF's 0..140): the way back is byte-exact
    assert "    range: [0.017453292519943295, 2.426007660272118]" in rc.read_text()
    assert back.read_bytes() == lr.read_bytes()
    assert main(["check", "--calibration", str(lr), "--urdf", str(URDF)]) == 0
    out = capsys.readouterr().out
    assert "8/8 joints matched (openarm-lerobot)" in out and "robot profile: openarm_follower_right" in out


@pytest.mark.slow
@pytest.mark.timeout(600)
def test_one_session_stores_the_zeros_and_writes_lerobots_file(tmp_path: Path) -> None:
    from robocal.workflows.autocal.sweep import SweepAutoRequest

    out, rep = tmp_path / "openarm_follower.json", tmp_path / "rep.json"
    request = SweepAutoRequest(URDF, "sim:openarm?seed=6", out, robot="openarm_follower_right", report=rep,
                               fmt="openarm-lerobot", write_zero=True)
    with openarm_session(request) as (outcome, sim):
        arm = sim.arm
        # judged by the simulator: each motor's stored zero is the joint's 0, one flash write each, all limp
        for name, motor in arm.motors.items():
            assert abs(math.degrees(arm.zero_error_rad(name))) < 0.1, name
            assert motor.flash_writes == 1 and not motor.enabled, name
        arm.power_cycle()  # the zero is in flash: after a power cycle the motors still read the joint angles
        for name in arm.motors:
            assert abs(math.degrees(arm.zero_error_rad(name))) < 0.1, name
    assert outcome.out == out and outcome.fmt == "openarm-lerobot"
    # the diagnostics are those of the new zeros: only J1 and J2, whose ranges cross +180° from the zero, warn
    # that a power cycle brings a reading beyond it back a turn off (exit 1)
    assert {j.name: j.warnings for j in outcome.result.joints if j.warnings} == {
        "openarm_right_joint1": ("wrap_in_travel",), "openarm_right_joint2": ("wrap_in_travel",)}
    assert outcome.exit_code == 1
    doc = json.loads(out.read_text())
    design = {"joint_1": (-80, 200), "joint_2": (-10, 190), "joint_3": (-90, 90), "joint_4": (0, 140),
              "joint_5": (-90, 90), "joint_6": (-45, 45), "joint_7": (-90, 90), "gripper": (-60, 0)}
    for motor, (lo, hi) in design.items():  # the measured range, rounded inward: never LeRobot's ±90
        assert lo <= doc[motor]["range_min"] <= lo + 1 and hi - 1 <= doc[motor]["range_max"] <= hi, motor
    stored = json.loads(rep.read_text())["zero_stored_at_deg"]
    assert set(stored) == set(RIGHT) and max(abs(v) for v in stored.values()) <= 0.05


@pytest.mark.slow
@pytest.mark.timeout(600)
def test_a_signal_after_the_first_zero_in_flash_stores_no_other_and_ends_the_run_after_the_file(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """From the first zero stored (a flash write cannot be taken back) to the file, a signal is held back: SIGTERM
    right after the first zero stores no further zero (the other joint goes limp with its zero as it was), the
    file is written for the zero that was stored, then the signal ends the run. The whole workflow in-process,
    judged by the simulated motors' flash writes (the fault harness does it over socketcand,
    tests/faults/test_damiao_faults.py, when a run reaches that instant under load; the store loop alone:
    tests/damiao/test_damiao_limp_all.py)."""
    import os
    import signal

    from robocal.backends.damiao.joint_driver import DamiaoJointDriver
    from robocal.errors import SignalInterrupt
    from robocal.workflows.autocal.damiao import SimAutoOpenArm, sim_openarm_opener
    from robocal.workflows.autocal.sweep import SweepAutoRequest, run_sweep_auto

    real_store = DamiaoJointDriver.store_zero
    stored: list[str] = []

    def store_then_sigterm(self: DamiaoJointDriver) -> None:
        real_store(self)
        stored.append(self.name)
        if len(stored) == 1:
            os.kill(os.getpid(), signal.SIGTERM)

    monkeypatch.setattr(DamiaoJointDriver, "store_zero", store_then_sigterm)
    out = tmp_path / "calibration.yaml"  # a format that holds offsets: J5 keeps its (unstored) zero's
    request = SweepAutoRequest(URDF, "sim:openarm?seed=4", out, robot="openarm_follower_right", fmt="lite-yaml",
                               joints=(RIGHT[4], RIGHT[7]), write_zero=True)
    holder: list[SimAutoOpenArm] = []
    try:
        with pytest.raises(SignalInterrupt) as info:
            run_sweep_auto(request, open_drivers_fn=sim_openarm_opener(holder))
        motors = holder[0].arm.motors
        # the profile zeroes the gripper first: its zero is in flash, J5's was never written
        assert {m: motors[m].flash_writes for m in ("gripper", "joint_5")} == {"gripper": 1, "joint_5": 0}
        assert not any(m.enabled for m in motors.values())
    finally:
        for sim in holder:
            sim.close()
    assert info.value.signum == signal.SIGTERM and stored == [RIGHT[7]]
    cal = read_calibration(out).calibration  # the file, then the signal: the gripper rezeroed (≈ 0), J5 not
    assert abs(math.degrees(cal.joint_map(RIGHT[7]).homing_offset)) < 0.5
    assert abs(math.degrees(cal.joint_map(RIGHT[4]).homing_offset)) > 0.5
