"""``robocal lerobot calibrate --auto`` through robocal.cli.main.main against the simulated arms with physics."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import pytest

from robocal.cli.main import main
from robocal.lerobot import MotorCalibration, read_calibration

from .conftest import calibrate_args

pytestmark = pytest.mark.timeout(600)


def run(
    tmp_path: Path, *extra: str, robot: str = "so101_follower", port: str = "sim", rid: str = "arm1"
) -> int:
    return main(calibrate_args(tmp_path, *extra, robot=robot, port=port, robot_id=rid))


@pytest.mark.slow
def test_auto_writes_the_manual_procedures_file(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert run(tmp_path, rid="manual") == 0  # the hand procedure on the same simulated arm
    capsys.readouterr()
    assert run(tmp_path, "--auto", "--yes", "--joints", "shoulder_pan,gripper", rid="auto") == 0
    out = capsys.readouterr()
    folder = tmp_path / "robots" / "so_follower"
    manual, auto = folder / "manual.json", folder / "auto.json"
    assert f"calibration saved to {auto} and written to the motors" in out.out
    assert "shoulder_pan: searching its stops at 20°/s, cap 0.48 N·m" in out.err
    assert (
        "kept the calibration their EEPROM holds: shoulder_lift, elbow_flex, wrist_flex, wrist_roll"
        in out.out
    )
    m, a = read_calibration(manual), read_calibration(auto)
    # the same format: keys, order, indentation; the same numbers within the press into the stop (≤ 2 ticks)
    assert list(json.loads(auto.read_text())) == list(json.loads(manual.read_text()))
    assert auto.read_text().startswith('{\n    "shoulder_pan": {\n        "id": 1,\n        "drive_mode": 0,')
    assert m["shoulder_pan"] == MotorCalibration(1, 0, 53, 847, 3247)
    assert a["shoulder_pan"].homing_offset == 53
    assert abs(a["shoulder_pan"].range_min - 847) <= 2 and abs(a["shoulder_pan"].range_max - 3247) <= 2
    g = a["gripper"]  # simulated stops 2000..3400: the middle reads 2047
    assert g.range_min + g.homing_offset == pytest.approx(2000, abs=2)
    assert g.range_max + g.homing_offset == pytest.approx(3400, abs=2)
    assert a["elbow_flex"] == MotorCalibration(3, 0, 0, 0, 4095)  # not searched: its (blank) EEPROM


@pytest.mark.slow
def test_auto_koch_current_based_gripper(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert run(tmp_path, "--auto", "--yes", "--joints", "gripper", robot="koch_follower") == 0
    cals = read_calibration(tmp_path / "robots" / "koch_follower" / "arm1.json")
    g = cals["gripper"]  # Dynamixel: Present = Actual + Homing_Offset; simulated stops 2000..3000
    assert g.range_min - g.homing_offset == pytest.approx(2000, abs=3)
    assert g.range_max - g.homing_offset == pytest.approx(3000, abs=3)
    assert "cap 0.13 N·m" in capsys.readouterr().err


@pytest.mark.slow
def test_missing_stop_exit_3_nothing_written_and_partial(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    port = "sim?missing=gripper"
    assert run(tmp_path, "--auto", "--yes", "--joints", "gripper", port=port) == 3
    err = capsys.readouterr().err
    lines = [ln for ln in err.splitlines() if ln.startswith("error:")]
    assert len(lines) == 1 and "gripper: missing_stop" in lines[0] and "Traceback" not in err
    assert not (tmp_path / "robots").exists()
    assert run(tmp_path, "--auto", "--yes", "--joints", "gripper,elbow_flex", "--partial", port=port) == 1
    out = capsys.readouterr()
    assert "written with --partial although gripper: missing_stop" in out.err
    cals = read_calibration(tmp_path / "robots" / "so_follower" / "arm1.json")
    assert cals["gripper"] == MotorCalibration(6, 0, 0, 0, 4095)  # failed: its EEPROM as it was
    assert cals["elbow_flex"].range_max - cals["elbow_flex"].range_min == pytest.approx(2250, abs=4)


@pytest.mark.slow
def test_ctrl_c_exit_130_nothing_written(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    from robocal.cli import _autocal

    calls = [0]

    def sample(self: Any, *args: Any) -> None:
        calls[0] += 1
        if calls[0] == 50:
            raise KeyboardInterrupt

    monkeypatch.setattr(_autocal.AutoLiveView, "sample", sample)
    assert run(tmp_path, "--auto", "--yes", "--joints", "gripper") == 130
    err = capsys.readouterr().err
    assert (
        "error: interrupted: every motor is limp, every register the search changed was written back" in err
    )
    assert not (tmp_path / "robots").exists()


@pytest.mark.slow
@pytest.mark.parametrize(
    ("extra", "port", "message"),
    [
        (["--joints", "gripper"], "sim", "error: --joints only apply with --auto"),
        (["--auto", "--yes", "--use-file"], "sim", "error: --auto cannot be combined with --use-file"),
        (
            ["--auto", "--yes", "--joints", "elbow,gripper"],
            "sim",
            "--joints: no auto-calibration entry for elbow",
        ),
        (["--auto", "--yes"], "sim?missing=elbow", "missing: no joint(s) elbow on a so101_follower"),
        (["--auto", "--yes"], "sim?fog=1", "fog"),
        (["--auto"], "sim", "pass --yes to skip the question in a script"),
    ],
)
def test_bad_auto_options_exit_2_before_anything_moves(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], extra: list[str], port: str, message: str
) -> None:
    assert run(tmp_path, *extra, port=port) == 2
    err = capsys.readouterr().err
    assert message in err and err.count("error:") == 1
    assert not (tmp_path / "robots").exists()


def test_leader_arm_has_no_auto_section(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert run(tmp_path, "--auto", "--yes", robot="so101_leader") == 2
    assert "so101_leader has no auto_calibration section" in capsys.readouterr().err


def test_a_follower_without_an_auto_section_is_not_called_a_leader(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    # the SO-100 follower drives itself, but no stop angles were measured for it: the message said leader arms
    assert run(tmp_path, "--auto", "--yes", robot="so100_follower") == 2
    err = capsys.readouterr().err
    assert err.count("error:") == 1 and "so100_follower has no auto_calibration section" in err
    assert "built-in arms that have it: koch_follower, so101_follower;" in err
    assert "write the section into a profile file of your own" in err
    assert not (tmp_path / "robots").exists()


@pytest.mark.parametrize(
    ("extra", "port"),
    [(["--auto", "--yes"], "sim"), (["--auto", "--yes"], "sim?seed=3&transport=inproc"), ([], "sim")],
)
def test_a_profile_file_on_the_simulated_port_is_refused_naming_the_arms_it_simulates(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], extra: list[str], port: str
) -> None:
    """Before: --auto said "unknown robot 'myarm'; valid: so101_follower, ...", although a profile file is a valid
    --robot (on a real port it calibrates that arm); without --auto "no simulated truth ... (from Python, pass
    truth=)". The simulator has the built-in arms only (their stops are its physics), so it says that."""
    shipped = Path(__file__).parents[2] / "src/robocal/data/profiles/so101_follower.yaml"
    profile = tmp_path / "myarm.yaml"
    profile.write_text(shipped.read_text().replace("\nname: so101_follower\n", "\nname: myarm\n"))
    assert run(tmp_path, *extra, robot=str(profile), port=port) == 2
    out, err = capsys.readouterr()
    assert (out, err) == ("", (
        f"error: --port {port!r}: the simulator has the built-in arms only (koch_follower, koch_leader, "
        "so100_follower, so100_leader, so101_follower, so101_leader); robot 'myarm' (a profile file) is not one "
        "of them: give one of those to --robot, or the real arm's port\n"
    ))
    assert not (tmp_path / "robots").exists()
