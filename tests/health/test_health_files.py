"""The calibration-files route (issue 30): the generator's two LeRobot files make the injected offset the way a
range recorded short at one end does, and the check names the joint from them where the data has no range end."""

from __future__ import annotations

import json
import math
from pathlib import Path

import pytest

from robocal.backends.sim.teleop import TELEOP_ARMS, TeleopFaults, simulate_sessions
from robocal.cli.main import main
from robocal.dataset.teleop_calibration import SCATTER_DEG, calibration_pair
from robocal.dataset.teleop_sim import generate_teleop_datasets
from robocal.errors import UsageError

TICKS_PER_DEG = 4095 / 360


def test_a_17_degree_follower_offset_is_a_range_recorded_34_degrees_short_at_its_upper_end() -> None:
    faults = TeleopFaults(offset_joint="elbow_flex", offset_deg=17.0, offset_arm="follower")
    (session,) = simulate_sessions(TELEOP_ARMS["so101"], [3], [faults], episodes=1, episode_s=1.0)
    leader, follower = calibration_pair(session)
    design = 2 * 96.83
    for cal, e in ((leader["elbow_flex"], 0.0), (follower["elbow_flex"], 17.0)):
        span = (cal.range_max - cal.range_min) / TICKS_PER_DEG
        mid = 0.5 * (cal.range_min + cal.range_max)
        assert design - 2 * abs(e) - 2 * SCATTER_DEG - 0.1 <= span <= design - 2 * abs(e) + 0.1
        for true_deg in (-50.0, 0.0, 40.0):  # LeRobot's DEGREES value of a true angle reads it + e
            present = 2047 + (true_deg + e) * TICKS_PER_DEG
            assert (present - mid) * 360 / 4095 == pytest.approx(true_deg + e, abs=0.1)
        upper_short = 96.83 - (cal.range_max - 2047) / TICKS_PER_DEG + e  # the true angle of the recorded end
        assert upper_short == pytest.approx(2 * e, abs=SCATTER_DEG + 0.1)
    assert (follower["wrist_roll"].range_min, follower["wrist_roll"].range_max) == (0, 4095)  # a full turn


def test_files_go_with_degrees(tmp_path: Path) -> None:
    with pytest.raises(UsageError, match="calibration files go with degrees"):
        generate_teleop_datasets(tmp_path, "koch", [1], [TeleopFaults()], use_degrees=False, calibration_files=True)


def _check(root: Path, report: Path) -> tuple[int, dict[str, object]]:
    code = main(["dataset", "health", str(root), "--robot", "koch_follower", "--use-degrees", "--report", str(report),
                 "--leader-calibration", str(root.with_name(root.name + ".leader.json")),
                 "--follower-calibration", str(root.with_name(root.name + ".follower.json"))])  # fmt: skip
    return code, json.loads(report.read_text())


@pytest.mark.slow
def test_a_leader_offset_without_range_end_contact_is_named_from_the_files(tmp_path: Path) -> None:
    faults = [TeleopFaults(offset_joint="shoulder_lift", offset_deg=-17.0, offset_arm="leader"), TeleopFaults()]
    roots = generate_teleop_datasets(tmp_path, "koch", [7, 8], faults, episodes=2, p_end=0.0, calibration_files=True)
    truth = json.loads(roots[0].with_name(roots[0].name + ".truth.json").read_text())["joints"]["shoulder_lift"]
    assert not truth["follower_contact"]
    code, rep = _check(roots[0], tmp_path / "off.json")
    joint = rep["joints"]["shoulder_lift"]  # type: ignore[index]
    assert code == 1 and rep["flagged"] == ["shoulder_lift"]
    assert joint["status"] == "suspect"
    for end in joint["range_ends"]:  # a together end: its excess under its own band, never wider than the symmetric
        assert end["kind"] == "together" and end["excess"] <= end["band"] <= joint["model_band"]
    (why,) = [r for r in joint["reasons"] if r.startswith("recorded ranges differ: leader 15")]
    gap = float(why.split("a range recorded ")[1].split("°")[0])
    assert math.isclose(gap, 34.0, abs_tol=2 * SCATTER_DEG + 0.2)
    code, rep = _check(roots[1], tmp_path / "clean.json")
    assert code == 0 and rep["flagged"] == []


@pytest.mark.slow
def test_a_full_turn_wrist_roll_offset_the_files_cannot_carry_is_unobservable_and_says_why(tmp_path: Path) -> None:
    # lerobot#3758's 17° on the SO-101's wrist_roll, on the follower, never taken near a stop: LeRobot records
    # wrist_roll as a full turn (0..4095), so neither the data nor the files can show it; it must not read "ok"
    faults = [TeleopFaults(offset_joint="wrist_roll", offset_deg=17.0, offset_arm="follower")]
    (root,) = generate_teleop_datasets(tmp_path, "so101", [4], faults, episodes=2, p_end=0.0, calibration_files=True)
    report = tmp_path / "h.json"
    code = main(["dataset", "health", str(root), "--robot", "so101_follower", "--report", str(report),
                 "--leader-calibration", str(root.with_name(root.name + ".leader.json")),
                 "--follower-calibration", str(root.with_name(root.name + ".follower.json"))])  # fmt: skip
    joint = json.loads(report.read_text())["joints"]["wrist_roll"]
    assert code == 0 and joint["status"] == "unobservable"
    assert joint["offset_deg"] is None and joint["ci_deg"] is None
    assert joint["reasons"] == [
        "no range-end contact",
        "recorded as a full turn in the calibration files: its zero is the homing pose, which the files do not "
        "carry; only the follower held at a stop can show its offset",
    ]


@pytest.mark.parametrize("bad", ["urdf", "no gripper"])
def test_a_calibration_file_that_is_not_the_arms_lerobot_file_is_refused_naming_it(
    bad: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """Before, a URDF given as --follower-calibration was read as a joint map (radians, no recorded range) and
    the check ran on that: exit 0; a LeRobot file without the gripper failed with "LeRobot calibration: no motor
    named gripper", naming neither the file nor the option."""
    (root,) = generate_teleop_datasets(tmp_path, "so101", [3], [TeleopFaults()], episodes=1, episode_s=1.0,
                                       calibration_files=True)  # fmt: skip
    leader = root.with_name(root.name + ".leader.json")
    follower = tmp_path / ("f.urdf" if bad == "urdf" else "f.json")
    if bad == "urdf":
        follower.write_bytes((Path(__file__).parents[2] / "src/robocal/data/so101_new_calib.urdf").read_bytes())
        needle = f"error: --follower-calibration {follower}: not a LeRobot calibration file;"
    else:
        data = json.loads(root.with_name(root.name + ".follower.json").read_text())
        del data["gripper"]
        follower.write_text(json.dumps(data))
        needle = f"error: --follower-calibration {follower}: no motor named gripper (the dataset's joints: shoulder_pan"
    before = follower.read_bytes()
    report = tmp_path / "h.json"
    code = main(["dataset", "health", str(root), "--report", str(report), "--leader-calibration", str(leader),
                 "--follower-calibration", str(follower)])  # fmt: skip
    err = capsys.readouterr().err
    assert code == 2
    lines = err.splitlines()
    assert len(lines) == 1 and lines[0].startswith(needle), err
    assert not report.exists() and not report.with_suffix(".png").exists()
    assert follower.read_bytes() == before
