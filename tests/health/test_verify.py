"""``lerobot calibrate --auto --verify`` (issue 30 item 2): the drift of a stored calibration, nothing written.

Judged on the physics simulator: the stored calibration is the simulated arm's true one (its stops from the
arm's truth) with a drift injected into one joint's homing offset (file and EEPROM alike); the estimate must be
within 0.3° of it, the EEPROM as it was and the file's bytes unchanged.
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import pytest

from robocal.cli.main import main
from robocal.core.health.drift import offset_drift, range_drift
from robocal.workflows.lerobot import robot_spec
from robocal.workflows.lerobot.auto import auto_section
from robocal.workflows.lerobot.verify import DEFAULT_TOLERANCE_DEG, VerifyRequest
from robocal.workflows.lerobot.verify_sim import verify_drift_run

COUNT_DEG = 360 / 4096


def test_drift_is_the_shift_of_the_middle_with_half_the_ends_disagreement_as_uncertainty() -> None:
    res = 4096
    stored = (1000.0, 3000.0)

    def rad(ticks: float) -> float:
        return ticks * 2 * math.pi / res

    d = range_drift("j", (rad(1023), rad(3023)), stored, res, 2.0)
    assert d.drift_deg == pytest.approx(23 * COUNT_DEG)
    assert (d.lower_deg, d.upper_deg) == (pytest.approx(23 * COUNT_DEG), pytest.approx(23 * COUNT_DEG))
    assert d.uncertainty_deg == pytest.approx(COUNT_DEG)
    assert d.flagged  # 2.02° > 2°
    d = range_drift("j", (rad(990), rad(3030)), stored, res, 2.0)  # the span grew by 40 counts: not an offset
    assert d.drift_deg == pytest.approx(10 * COUNT_DEG)
    assert d.uncertainty_deg == pytest.approx(math.hypot(20 * COUNT_DEG, COUNT_DEG))
    assert not d.flagged
    # a turn away (the driver's unwrapped frame): the same drift
    assert range_drift("j", (rad(1023 + res), rad(3023 + res)), stored, res, 2.0).drift_deg == pytest.approx(
        23 * COUNT_DEG
    )
    # a full-turn range is not its stops: only its middle
    full = range_drift("j", (rad(113), rad(3981)), (0.0, 4095.0), res, 2.0)
    assert full.drift_deg == pytest.approx(-0.5 * COUNT_DEG)
    assert full.uncertainty_deg == pytest.approx(COUNT_DEG) and math.isnan(full.lower_deg)


def test_the_default_tolerance_is_two_degrees_and_a_bad_one_is_refused(tmp_path: Path) -> None:
    assert DEFAULT_TOLERANCE_DEG == 2.0
    spec, section = robot_spec("so101_follower"), auto_section("so101_follower")
    with pytest.raises(Exception, match=r"--tolerance-deg: expected a positive number of degrees, got -1.0"):
        VerifyRequest(spec, section, tmp_path / "x.json", tolerance_deg=-1.0)


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["--verify"], "error: --verify only apply with --auto"),
        (
            ["--auto", "--verify", "--partial"],
            "error: --verify writes nothing: --partial cannot be combined with it",
        ),
        (
            ["--auto", "--verify", "--tolerance-deg", "0"],
            "error: --tolerance-deg: expected a positive number",
        ),
        (["--auto", "--verify", "--yes"], "error: no stored calibration at "),
    ],
)
def test_verify_refusals_are_one_line_and_exit_2_before_the_port_opens(
    args: list[str], message: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    base = ["lerobot", "calibrate", "--robot", "so101_follower", "--port", "/nonexistent/tty", "--id", "t"]
    rc = main([*base, "--calibration-dir", str(tmp_path), *args])
    out, err = capsys.readouterr()
    assert rc == 2 and out == ""
    assert err.startswith(message) and err.count("\n") == 1
    assert list(tmp_path.iterdir()) == []


@pytest.mark.slow
@pytest.mark.parametrize(
    ("robot", "seed", "joint", "drift_counts"),
    [
        ("so101_follower", 1, "elbow_flex", 23),
        ("so101_follower", 2, "shoulder_lift", -40),
        ("so101_follower", 4, "wrist_flex", 12),
        ("so101_follower", 5, "shoulder_pan", -200),
        ("koch_follower", 1, "elbow_flex", 23),
        ("koch_follower", 2, "shoulder_lift", -40),
        ("koch_follower", 3, "wrist_flex", 150),
    ],
)
def test_verify_finds_an_injected_drift_within_0_3_degrees_and_writes_nothing(
    robot: str, seed: int, joint: str, drift_counts: int
) -> None:
    """SO-101 (Feetech: the offset lowers the reading) and Koch (Dynamixel: it raises it), the benchmark's run."""
    run = verify_drift_run(robot, seed, joint, drift_counts)
    assert run.unchanged  # EEPROM, file bytes, folder as they were; every torque off
    searched = {j.name for j in auto_section(robot).searched_joints}
    assert {j.name for j in run.result.joints} == searched
    sign = -1 if robot.startswith("so101") else 1  # Present = Actual ∓ Homing_Offset
    assert run.injected_deg == pytest.approx(sign * drift_counts * COUNT_DEG)
    assert run.estimate_deg == pytest.approx(run.injected_deg, abs=0.3)
    assert run.others_deg < 0.3
    flagged = abs(run.injected_deg) > 2.0
    assert [j.name for j in run.result.joints if j.flagged] == ([joint] if flagged else [])
    assert run.result.exit_code == (1 if flagged else 0)
    assert run.result.search_s < 60.0  # the simulated arm's clock: under a minute for every joint


@pytest.mark.slow
def test_cli_verify_prints_the_drift_table_and_exits_1_past_the_tolerance(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    port = "sim?seed=3&transport=inproc"
    base = [
        "lerobot",
        "calibrate",
        "--auto",
        "--robot",
        "so101_follower",
        "--port",
        port,
        "--id",
        "t",
        "--yes",
    ]
    assert main([*base, "--calibration-dir", str(tmp_path)]) == 0
    (path,) = tmp_path.rglob("t.json")
    cals = json.loads(path.read_text())
    cals["elbow_flex"]["homing_offset"] += 46  # 4.04°
    path.write_text(json.dumps(cals, indent=4))
    before = path.read_bytes()
    capsys.readouterr()
    rc = main([*base, "--calibration-dir", str(tmp_path), "--verify"])
    out, err = capsys.readouterr()
    assert rc == 1
    row = next(line for line in out.splitlines() if "elbow_flex" in line)
    assert "DRIFTED" in row and "-4.0" in row
    assert sum("DRIFTED" in line for line in out.splitlines()) == 1
    assert "nothing was written" in out
    assert "warning: elbow_flex drifted more than 2° from" in err
    assert path.read_bytes() == before


@pytest.mark.slow
def test_a_stored_offset_no_register_can_hold_is_refused_before_anything_moves(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """The drift is taken modulo a turn: a stored homing_offset of 2147483647 (4095 modulo 4096) read "ok", exit 0,
    though no STS3215 register (sign-magnitude, ±2047) can hold it: that file was never on this arm."""
    base = ["lerobot", "calibrate", "--auto", "--robot", "so101_follower", "--port", "sim?seed=3&transport=inproc"]
    base += ["--id", "t", "--yes", "--calibration-dir", str(tmp_path)]
    assert main(base) == 0
    (path,) = tmp_path.rglob("t.json")
    cals = json.loads(path.read_text())
    cals["elbow_flex"]["homing_offset"] = 2147483647
    path.write_text(json.dumps(cals, indent=4))
    before = path.read_bytes()
    capsys.readouterr()
    rc = main([*base, "--verify"])
    out, err = capsys.readouterr()
    assert rc == 2 and "DRIFTED" not in out and "ok" not in out.split()
    assert err.count("error:") == 1 and "Traceback" not in err
    assert "motor 'elbow_flex': Homing_Offset 2147483647 cannot be on the motor" in err and "nothing moved" in err
    assert path.read_bytes() == before


def test_offset_drift_is_the_direction_times_the_offset_change_modulo_a_turn() -> None:
    d = offset_drift("j", -1, 0.50 + 2 * math.pi, 0.465, 0.0, 1e-4, 2.0)
    assert d.drift_deg == pytest.approx(-math.degrees(0.035))
    assert d.uncertainty_deg == pytest.approx(math.degrees(1e-4))
    assert d.flagged and math.isnan(d.lower_deg)  # 2.005° > 2°
    d = offset_drift("j", 1, 0.50, 0.40, 0.02, 1e-4, 2.0)  # the span is 0.02 rad off: ± half of it
    assert d.drift_deg == pytest.approx(math.degrees(0.1)) and d.flagged
    assert d.uncertainty_deg == pytest.approx(math.degrees(math.hypot(0.01, 1e-4)))


@pytest.mark.slow
def test_sweep_auto_verify_finds_a_drifted_offset_on_the_simulated_lite_and_writes_nothing(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    from robocal.backends.sim.lite import lite_urdf_text

    urdf = tmp_path / "lite.urdf"
    urdf.write_text(lite_urdf_text())
    out = tmp_path / "calibration.yaml"
    joints = "left_elbow_pitch,right_shoulder_pitch"
    base = ["sweep", "--auto", "--urdf", str(urdf), "--source", "sim:lite?seed=3", "--out", str(out), "--yes"]
    assert main([*base, "--joints", joints]) in (0, 1)  # 1: the wrap-in-travel warnings of the simulated Lite
    text = out.read_text()
    key = "right_shoulder_pitch:\n  id: 21\n  direction: 1\n  homing_offset: "
    start = text.index(key) + len(key)
    end = text.index("\n", start)
    stored = float(text[start:end])
    out.write_text(text[:start] + repr(stored + 0.035) + text[end:])  # stored 2.005° off: reads 2.005° less
    before = out.read_bytes()
    capsys.readouterr()
    rc = main([*base, "--joints", joints, "--verify"])
    printed, err = capsys.readouterr()
    assert rc == 1
    rows = {
        line.split()[1]: line.split()
        for line in printed.splitlines()
        if line.startswith("│ ") and "_" in line
    }
    assert float(rows["right_shoulder_pitch"][3]) == pytest.approx(-2.005, abs=0.3)
    assert "DRIFTED" in rows["right_shoulder_pitch"]
    assert abs(float(rows["left_elbow_pitch"][3])) < 0.3 and "ok" in rows["left_elbow_pitch"]
    assert "warning: right_shoulder_pitch drifted more than 2° from" in err
    assert out.read_bytes() == before
    assert sorted(p.name for p in tmp_path.iterdir()) == ["calibration.yaml", "lite.urdf"]


def test_a_leader_is_verified_by_hand_read_only_and_its_drifted_joint_named(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    from robocal.backends.sim.lerobot_arms import DEFAULT_TRUTH

    spec = robot_spec("so101_leader")
    truth = DEFAULT_TRUTH["so101_leader"]
    cals = {
        m.name: {
            "id": m.motor_id,
            "drive_mode": 0,
            "homing_offset": 0,
            "range_min": int(truth[m.name].stop_low_ticks),
            "range_max": int(truth[m.name].stop_high_ticks),
        }
        for m in spec.motors
    }
    cals["elbow_flex"]["homing_offset"] += 30  # the stored calibration reads 30 counts (2.64°) less
    path = tmp_path / "teleoperators" / "so_leader" / "l.json"
    path.parent.mkdir(parents=True)
    path.write_text(json.dumps(cals, indent=4))
    before = path.read_bytes()
    base = [
        "lerobot",
        "calibrate",
        "--auto",
        "--verify",
        "--robot",
        "so101_leader",
        "--port",
        "sim",
        "--id",
        "l",
    ]
    rc = main([*base, "--calibration-dir", str(tmp_path)])
    out, err = capsys.readouterr()
    assert rc == 1
    rows = {line.split()[1]: line.split() for line in out.splitlines() if line.startswith("│ ")}
    assert set(rows) == {
        "shoulder_pan",
        "shoulder_lift",
        "elbow_flex",
        "wrist_flex",
        "gripper",
    }  # not wrist_roll
    assert float(rows["elbow_flex"][3]) == pytest.approx(-30 * COUNT_DEG, abs=0.01)
    assert "DRIFTED" in rows["elbow_flex"] and sum("DRIFTED" in r for r in rows.values()) == 1
    assert "nothing was written (the arm was only read)" in out
    assert "warning: elbow_flex drifted more than 2° from" in err
    assert path.read_bytes() == before


def test_sweep_verify_of_a_joint_the_file_stores_no_offset_for_is_refused_before_anything_moves(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """Before: the joint was searched (moved to both stops) and left out of the drift table without a word; with
    it alone, an empty table and exit 0: nothing flagged, nothing verified."""
    from robocal.backends.sim.lite import LITE_JOINTS, lite_urdf_text

    urdf = tmp_path / "lite.urdf"
    urdf.write_text(lite_urdf_text())
    out = tmp_path / "calibration.yaml"
    out.write_text("".join(f"{j.name}:\n  id: {j.can_id}\n  direction: {j.direction}\n  homing_offset: 0.0\n"
                           for j in LITE_JOINTS if j.name != "left_elbow_pitch"))  # fmt: skip
    before = out.read_bytes()
    rc = main(["sweep", "--auto", "--verify", "--urdf", str(urdf), "--source", "sim:lite?seed=3", "--out", str(out),
               "--yes", "--joints", "left_elbow_pitch,right_shoulder_pitch"])  # fmt: skip
    printed, err = capsys.readouterr()
    assert rc == 2 and printed == ""
    assert err == (
        f"error: --verify: {out} stores no offset for left_elbow_pitch; calibrate those joints first or leave them "
        "out of --joints\n"
    )
    assert out.read_bytes() == before
    assert sorted(p.name for p in tmp_path.iterdir()) == ["calibration.yaml", "lite.urdf"]


@pytest.mark.parametrize(("robot", "folder"), [("so101_follower", "robots"), ("so101_leader", "teleoperators")])
def test_a_folder_where_the_stored_calibration_should_be_is_named_as_a_folder(
    robot: str, folder: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """Before: "no stored calibration at ... (calibrate first)", for a path that exists."""
    kind = "so_follower" if robot.endswith("follower") else "so_leader"
    path = tmp_path / folder / kind / "t.json"
    path.mkdir(parents=True)
    rc = main(["lerobot", "calibrate", "--robot", robot, "--port", "/nonexistent/tty", "--id", "t",
               "--calibration-dir", str(tmp_path), "--auto", "--verify", "--yes"])  # fmt: skip
    out, err = capsys.readouterr()
    assert rc == 2 and out == ""
    assert err == f"error: LeRobot calibration {path}: is a directory, expected a file\n"
    assert path.is_dir() and list(path.iterdir()) == []
