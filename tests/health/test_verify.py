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
from robocal.workflows.lerobot.auto import auto_section, calibration_from_stops
from robocal.workflows.lerobot.auto_sim import auto_gravity_model, open_auto_arm
from robocal.workflows.lerobot.verify import DEFAULT_TOLERANCE_DEG, VerifyRequest, verify_calibration

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


def _true_calibration(spec, truth) -> dict[str, dict[str, int]]:  # type: ignore[no-untyped-def]
    """The arm's true calibration (its stops from the simulator's truth), LeRobot's JSON fields."""
    out = {}
    for m in spec.motors:
        t = truth[m.name]
        cal = calibration_from_stops(
            spec,
            m.name,
            4096,
            t.stop_low_ticks * 2 * math.pi / 4096,
            t.stop_high_ticks * 2 * math.pi / 4096,
            full_range=m.name in spec.full_turn,
        )
        out[m.name] = {
            "id": cal.id,
            "drive_mode": cal.drive_mode,
            "homing_offset": cal.homing_offset,
            "range_min": cal.range_min,
            "range_max": cal.range_max,
        }
    return out


@pytest.mark.slow
@pytest.mark.parametrize(
    ("seed", "joint", "drift_counts"),
    [(1, "elbow_flex", 23), (2, "shoulder_lift", -40), (4, "wrist_flex", 12), (5, "shoulder_pan", -200)],
)
def test_verify_finds_an_injected_drift_within_0_3_degrees_and_writes_nothing(
    seed: int, joint: str, drift_counts: int, tmp_path: Path
) -> None:
    spec, section = robot_spec("so101_follower"), auto_section("so101_follower")
    port = f"sim?seed={seed}&transport=inproc"
    with open_auto_arm(spec, port, section) as arm:
        cals = _true_calibration(spec, arm.sim.truth)
        cals[joint]["homing_offset"] += (
            drift_counts  # the stored calibration drifted: reads drift_counts less
        )
        path = tmp_path / "follower.json"
        path.write_text(json.dumps(cals, indent=4))
        for name, c in cals.items():  # the arm holds that stored calibration in its EEPROM
            servo = arm.sim.servo(name)
            servo.set_reg("Homing_Offset", c["homing_offset"])
            servo.set_reg("Min_Position_Limit", c["range_min"])
            servo.set_reg("Max_Position_Limit", c["range_max"])
        eeprom, file_bytes = arm.sim.eeprom(), path.read_bytes()
        request = VerifyRequest(
            spec, section, path, gravity_model=auto_gravity_model(spec, port, section, None)
        )
        result = verify_calibration(arm.bus, request, clock=arm.clock)
        assert arm.sim.eeprom() == eeprom
        assert {n: arm.sim.servo(n).get_reg("Torque_Enable") for n in cals} == dict.fromkeys(cals, 0)
    assert path.read_bytes() == file_bytes
    assert [p.name for p in tmp_path.iterdir()] == ["follower.json"]
    drift = {j.name: j for j in result.joints}
    assert set(drift) == {
        "shoulder_lift",
        "elbow_flex",
        "wrist_flex",
        "wrist_roll",
        "gripper",
        "shoulder_pan",
    }
    injected = -drift_counts * COUNT_DEG
    assert drift[joint].drift_deg == pytest.approx(injected, abs=0.3)
    assert all(abs(j.drift_deg) < 0.3 for j in result.joints if j.name != joint)
    assert [j.name for j in result.joints if j.flagged] == ([joint] if abs(injected) > 2.0 else [])
    assert result.exit_code == (1 if abs(injected) > 2.0 else 0)
    assert result.search_s < 60.0  # the simulated arm's clock: under a minute for every joint


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
