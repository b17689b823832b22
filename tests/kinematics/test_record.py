"""`robocal kinematics record` against the simulated SO-101 servo bus (real Feetech SDK on a pty)."""

from __future__ import annotations

import math
import queue
import subprocess
import sys
import threading
from pathlib import Path

import numpy as np
import pytest

from robocal.backends.sim.lerobot_arms import DEFAULT_TRUTH, SimArm
from robocal.core.lerobot import MotorCalibration
from robocal.errors import JointMismatchError, UsageError
from robocal.formats.kinematic_data import read_measurements
from robocal.lerobot import write_calibration
from robocal.workflows.kinematics.record import RecordRequest, record
from robocal.workflows.kinematics.record_arm import ArmSource, open_reader
from robocal.workflows.kinematics.sim import shipped_urdf
from robocal.workflows.lerobot import robot_spec

pytest.importorskip("scservo_sdk")

ROBOT = "so101_follower"
SPEC = robot_spec(ROBOT)
TICK = 2 * math.pi / 4095  # LeRobot DEGREES: 360° per 4095 ticks
CHAIN = ("shoulder_pan", "shoulder_lift", "elbow_flex", "wrist_flex", "wrist_roll")
TARGETS = np.array(
    [
        [0.30, -0.40, 0.50, 0.20, -1.00],
        [-0.60, 0.20, -0.30, -0.70, 0.80],
        [0.05, 0.90, 1.00, 0.40, 2.00],
    ]
)


def _homing() -> dict[str, int]:
    """Homing_Offset that puts each joint's mid pose at present 2047 (sign-magnitude: |h| <= 2047)."""
    return {n: (int(t.mid_ticks) - 2047 + 2048) % 4096 - 2048 for n, t in DEFAULT_TRUTH[ROBOT].items()}


def _calibration(path: Path) -> dict[str, MotorCalibration]:
    """A LeRobot calibration of the simulated arm: mid pose at present 2047, ranges at the hard stops."""
    h = _homing()
    cals = {}
    for m in SPEC.motors:
        t = DEFAULT_TRUTH[ROBOT][m.name]
        cals[m.name] = MotorCalibration(
            m.motor_id,
            0,
            h[m.name],
            (int(t.stop_low_ticks) - h[m.name]) % 4096,
            (int(t.stop_high_ticks) - h[m.name]) % 4096,
        )
    write_calibration(path, cals)
    return cals


def _actual_ticks(cals: dict[str, MotorCalibration], q_rad: np.ndarray) -> dict[str, float]:
    """Where each shaft must be so that LeRobot DEGREES reads ``q_rad`` (inverse of the export-urdf map)."""
    out = {}
    for name, q in zip(CHAIN, q_rad, strict=True):
        c = cals[name]
        mid = (c.range_min + c.range_max) / 2
        actual = mid + q / TICK + c.homing_offset
        t = DEFAULT_TRUTH[ROBOT][name]
        out[name] = actual + 4096 * round((t.mid_ticks - actual) / 4096)  # the turn inside the hard stops
    return out


@pytest.fixture
def arm(tmp_path: Path):
    eeprom = {n: {"Homing_Offset": h} for n, h in _homing().items()}
    with SimArm(SPEC, eeprom=eeprom) as sim:
        cals = _calibration(tmp_path / "cal.json")
        yield sim, cals, tmp_path / "cal.json"


def test_points_session_reads_the_joints_through_the_lerobot_calibration(arm, tmp_path: Path) -> None:
    sim, cals, cal_path = arm
    reader, chain = open_reader(ArmSource(lerobot_port=sim.port, robot=ROBOT, calibration_file=cal_path))
    assert chain.joint_names == CHAIN and chain.tip_link == "gripper_link"
    # the recorder switched every motor's torque off so the arm can be moved by hand
    assert all(sim.servo(m.name).get_reg("Torque_Enable") == 0 for m in SPEC.motors)
    answers: list[str] = []
    said: list[str] = []

    def ask(prompt: str) -> str:
        answers.append(prompt)
        if "move the arm" in prompt:
            n = int(prompt.split()[1].rstrip(":"))
            if n > len(TARGETS):
                return "q"
            sim.move(_actual_ticks(cals, TARGETS[n - 1]))
            return ""
        n = int(prompt.split()[1].rstrip(":"))
        return f"{100 + n} {-20.5 * n} 3.25"

    try:
        result = record(reader, chain, RecordRequest(tmp_path / "s.csv", kind="points"), ask=ask, say=said.append)
    finally:
        reader.close()
    assert result.measurements.n_poses == 3 and not result.skipped
    data, _ = read_measurements(tmp_path / "s.csv", "points", CHAIN)
    # whole ticks: the reading is within half a tick of the requested angle
    assert np.abs(data.q_rad - TARGETS).max() <= 0.5 * TICK + 1e-12
    assert data.p_world_m is not None
    assert data.p_world_m[1].tolist() == pytest.approx([0.102, -0.041, 0.00325])
    assert said[0].startswith("pose 1 recorded: shoulder_pan +0.30")


def test_pose_outside_the_urdf_limits_is_not_recorded_and_q_finishes(arm, tmp_path: Path) -> None:
    sim, cals, cal_path = arm
    reader, chain = open_reader(ArmSource(lerobot_port=sim.port, robot=ROBOT, calibration_file=cal_path))
    poses = [TARGETS[0], np.array([0.0, 0.0, 0.0, 0.0, -2.9]), TARGETS[1]]  # wrist_roll limit −2.74385
    said: list[str] = []
    moves = iter(poses)

    def ask(prompt: str) -> str:
        if "move the arm" in prompt:
            q = next(moves, None)
            if q is None:
                return "done"
            sim.move(_actual_ticks(cals, q))
            return ""
        return "P7" if "label" in prompt else ""

    try:
        result = record(reader, chain, RecordRequest(tmp_path / "t.csv", kind="touch"), ask=ask, say=said.append)
    finally:
        reader.close()
    assert result.measurements.n_poses == 2
    assert len(result.skipped) == 1
    assert (
        "joint wrist_roll = -2.9 is outside its URDF limits [-2.744, 2.841]; not recorded"
        in result.skipped[0]
    )
    data, labels = read_measurements(tmp_path / "t.csv", "touch", CHAIN)
    assert labels == ("P7",) and data.group is not None and data.group.tolist() == [0, 0]


def test_no_pose_writes_nothing(arm, tmp_path: Path) -> None:
    sim, _, cal_path = arm
    reader, chain = open_reader(ArmSource(lerobot_port=sim.port, robot=ROBOT, calibration_file=cal_path))

    def ask(prompt: str) -> str:
        raise EOFError

    try:
        with pytest.raises(UsageError, match="no pose was recorded; nothing written"):
            record(reader, chain, RecordRequest(tmp_path / "none.csv"), ask=ask, say=print)
    finally:
        reader.close()
    assert not (tmp_path / "none.csv").exists()


def test_joint_map_without_a_chain_joint_is_refused(tmp_path: Path) -> None:
    (tmp_path / "map.yaml").write_text(
        "format: robocal-joint-map\nversion: 1\njoints:\n  shoulder_pan: {direction: 1, homing_offset: 2047, "
        "scale: 0.0015343306}\n"
    )
    with pytest.raises(JointMismatchError, match=r"has no joint\(s\) shoulder_lift, elbow_flex"):
        open_reader(ArmSource(lerobot_port="/dev/null", robot=ROBOT, joint_map=tmp_path / "map.yaml"))


def test_replay_source(tmp_path: Path) -> None:
    rows = TARGETS
    (tmp_path / "rec.csv").write_text(
        "t,"
        + ",".join(CHAIN)
        + "\n"
        + "".join(f"{i * 0.1}," + ",".join(map(str, r)) + "\n" for i, r in enumerate(rows))
    )
    reader, chain = open_reader(
        ArmSource(urdf=shipped_urdf("so101"), tip_link="gripper_link", source=f"replay:{tmp_path / 'rec.csv'}")
    )
    groups = iter("AABB")

    def ask(prompt: str) -> str:
        return next(groups) if "socket" in prompt else ""

    try:
        result = record(reader, chain, RecordRequest(tmp_path / "g.csv", kind="gauge", poses=2), ask=ask, say=lambda m: None)
    finally:
        reader.close()
    assert result.measurements.q_rad.tolist() == rows[:2].tolist()
    assert (tmp_path / "g.csv").read_text().splitlines()[0] == "pose," + ",".join(CHAIN) + ",socket"


def _reader_thread(stream, q: queue.Queue[str]) -> None:
    for line in iter(stream.readline, ""):
        q.put(line)


@pytest.mark.slow
def test_cli_with_scripted_enter_presses(arm, tmp_path: Path) -> None:
    """The command as a person runs it: the arm is moved, then Enter; the test waits for each pose's line."""
    sim, cals, cal_path = arm
    out = tmp_path / "cli.csv"
    proc = subprocess.Popen(
        [sys.executable, "-m", "robocal", "kinematics", "record", "--lerobot-port", sim.port, "--robot", ROBOT,
         "--file", str(cal_path), "--kind", "gauge", "--out", str(out), "--poses", "2"],
        stdin=subprocess.PIPE, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
    )  # fmt: skip
    lines: queue.Queue[str] = queue.Queue()
    threading.Thread(target=_reader_thread, args=(proc.stderr, lines), daemon=True).start()
    assert proc.stdin is not None
    try:
        for n, socket in ((1, "A"), (2, "B")):
            sim.move(_actual_ticks(cals, TARGETS[n - 1]))
            proc.stdin.write(f"\n{socket}\n")
            proc.stdin.flush()
            while True:
                line = lines.get(timeout=60)
                if f"pose {n} recorded" in line:
                    break
        stdout, _ = proc.communicate(timeout=60)
    finally:
        if proc.poll() is None:
            proc.kill()
    assert proc.returncode == 0
    assert f"wrote {out} (2 poses)" in stdout
    data, _ = read_measurements(out, "gauge", CHAIN, distance_m=0.05)
    assert np.abs(data.q_rad - TARGETS[:2]).max() <= 0.5 * TICK + 1e-12
    assert data.group is not None and data.group.tolist() == [0, 1]


def test_cli_needs_one_joint_source(tmp_path: Path, capsys) -> None:
    from robocal.cli.main import main

    assert main(["kinematics", "record", "--out", str(tmp_path / "x.csv"), "--robot", ROBOT]) == 2
    assert capsys.readouterr().err.strip() == "error: give either --lerobot-port (with --robot) or --source"
    assert not (tmp_path / "x.csv").exists()


def test_planned_poses_are_shown_one_by_one(tmp_path: Path, capsys, monkeypatch) -> None:
    """``record --plan``: each prompt names the planned pose, each recorded pose says how far off it was."""
    import io

    from robocal.cli.main import main

    (tmp_path / "rec.csv").write_text(
        "t," + ",".join(CHAIN) + "\n" + "".join(f"{i * 0.1}," + ",".join(map(str, r)) + "\n" for i, r in enumerate(TARGETS))
    )
    plan = TARGETS[:2].copy()
    plan[1, 2] += math.radians(3.0)  # the arm reaches pose 2 with elbow_flex 3° short
    (tmp_path / "plan.csv").write_text(
        "pose," + ",".join(CHAIN) + "\n" + "".join(f"{i + 1}," + ",".join(str(float(v)) for v in r) + "\n" for i, r in enumerate(plan))
    )
    args = [
        "kinematics", "record", "--source", f"replay:{tmp_path / 'rec.csv'}", "--urdf", str(shipped_urdf("so101")),
        "--tip-link", "gripper_link", "--kind", "touch", "--out", str(tmp_path / "t.csv"), "--plan", str(tmp_path / "plan.csv"),
    ]  # fmt: skip
    monkeypatch.setattr("sys.stdin", io.StringIO("\nP1\n\nP1\n\nP1\n"))
    assert main(args) == 0
    err = capsys.readouterr().err
    assert (
        "pose 1: move the arm to shoulder_pan +17.2°, shoulder_lift -22.9°, elbow_flex +28.6°, wrist_flex +11.5°, "
        "wrist_roll -57.3°, then press Enter" in err
    )
    assert "(off the plan by at most +0.0°, shoulder_pan)" in err
    assert "(off the plan by at most -3.0°, elbow_flex)" in err
    assert "pose 3" not in err  # the plan has two poses: the session ends after them
    assert len((tmp_path / "t.csv").read_text().splitlines()) == 3
    # a planned pose outside the URDF limits is refused before the session starts; nothing is written
    plan[0, 2] = 3.5
    (tmp_path / "plan.csv").write_text(
        "pose," + ",".join(CHAIN) + "\n" + "".join(f"{i + 1}," + ",".join(str(float(v)) for v in r) + "\n" for i, r in enumerate(plan))
    )
    args[args.index("--out") + 1] = str(tmp_path / "u.csv")
    assert main(args) == 2
    err = capsys.readouterr().err
    assert f"{tmp_path / 'plan.csv'}: pose 1" in err and "elbow_flex" in err and err.count("error:") == 1
    assert not (tmp_path / "u.csv").exists()


def test_a_contact_plan_names_the_point_and_answers_for_it(tmp_path: Path, capsys, monkeypatch) -> None:
    """A touch plan's ``group`` column: the prompt says which point to touch, and Enter takes it."""
    import io

    from robocal.cli.main import main

    (tmp_path / "rec.csv").write_text(
        "t," + ",".join(CHAIN) + "\n" + "".join(f"{i * 0.1}," + ",".join(map(str, r)) + "\n" for i, r in enumerate(TARGETS))
    )
    (tmp_path / "plan.csv").write_text(
        "pose," + ",".join(CHAIN) + ",group\n"
        + "".join(f"{i + 1}," + ",".join(str(float(v)) for v in r) + f",{g}\n" for i, (r, g) in enumerate(zip(TARGETS, ("P2", "P1", "P2"), strict=True)))
    )
    args = [
        "kinematics", "record", "--source", f"replay:{tmp_path / 'rec.csv'}", "--urdf", str(shipped_urdf("so101")),
        "--tip-link", "gripper_link", "--kind", "touch", "--out", str(tmp_path / "t.csv"), "--plan", str(tmp_path / "plan.csv"),
    ]  # fmt: skip
    monkeypatch.setattr("sys.stdin", io.StringIO("\n\n\nP3\n\n\n"))  # pose 2: the user touched P3 instead
    assert main(args) == 0
    err = capsys.readouterr().err
    assert "wrist_roll -57.3°, touching P2, then press Enter" in err
    assert "pose 2: label of the touched point [P1]" in err
    data, labels = read_measurements(tmp_path / "t.csv", "touch", CHAIN)
    assert [labels[g] for g in data.group] == ["P2", "P3", "P2"]
