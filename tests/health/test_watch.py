"""``robocal health watch`` (issue 30 item 3): flags as they happen on a simulated arm, read-only, exit codes."""

from __future__ import annotations

import json
import math
import re
from collections.abc import Iterator
from pathlib import Path

import pytest

from robocal.backends.sim.lerobot_arms import DEFAULT_TRUTH, SimArm
from robocal.cli.main import main
from robocal.core.health import HealthFlag
from robocal.workflows.health import WatchRequest, watch
from robocal.workflows.lerobot import robot_spec

TRUTH = DEFAULT_TRUTH["so101_follower"]
WRIST_FLEX_OFFSET = -1943  # its travel crosses the encoder seam: this offset puts its middle at 2047
SHORT_TICKS = 100  # elbow_flex's recorded range ends this far below its stop


def _calibration(path: Path) -> Path:
    """The arm's calibration: homing offset 0 (wrist_flex: WRIST_FLEX_OFFSET), ranges at the truth's stops."""
    cals = {}
    for i, (name, t) in enumerate(TRUTH.items()):
        offset = WRIST_FLEX_OFFSET if name == "wrist_flex" else 0
        # Present_Position = actual − Homing_Offset, within one turn
        lo, hi = (t.stop_low_ticks - offset) % 4096, (t.stop_high_ticks - offset) % 4096
        if name == "elbow_flex":
            hi -= SHORT_TICKS
        if name == "wrist_roll":
            lo, hi = 0, 4095
        cals[name] = {
            "id": i + 1,
            "drive_mode": 0,
            "homing_offset": offset,
            "range_min": int(lo),
            "range_max": int(hi),
        }
    path.write_text(json.dumps(cals, indent=4))
    return path


@pytest.fixture
def arm() -> Iterator[SimArm]:
    with SimArm(
        robot_spec("so101_follower"),
        eeprom={"wrist_flex": {"Homing_Offset": WRIST_FLEX_OFFSET}},
        transport="inproc",
    ) as a:
        yield a


class FakeClock:
    """10 ms per reading; sleeping does not wait."""

    def __init__(self) -> None:
        self.t = 100.0

    def __call__(self) -> float:
        self.t += 0.005  # read twice per tick (the reading, the pause)
        return self.t

    def sleep(self, dt: float) -> None:
        self.t += dt


def test_a_slipped_joint_and_a_reading_past_its_recorded_range_are_flagged_without_writing(
    arm: SimArm, tmp_path: Path
) -> None:
    cal = _calibration(tmp_path / "follower.json")
    cal_bytes = cal.read_bytes()
    eeprom = arm.eeprom()
    torque = {n: arm.servo(n).get_reg("Torque_Enable") for n in TRUTH}
    goal = {n: arm.servo(n).get_reg("Goal_Position") for n in TRUTH}
    flags: list[tuple[int, HealthFlag]] = []
    tick = [0]

    def on_tick(k: int) -> None:
        tick[0] = k
        if k == 10:
            arm.move({"shoulder_pan": TRUTH["shoulder_pan"].mid_ticks + 30})  # 2.6° in one tick: a slip
        if k == 30:
            arm.move({"elbow_flex": TRUTH["elbow_flex"].stop_high_ticks})  # 100 ticks past its recorded range
        if k == 50:
            raise KeyboardInterrupt

    clock = FakeClock()
    request = WatchRequest(lerobot_port=arm.port, robot="so101_follower", calibration_file=cal)
    with pytest.raises(KeyboardInterrupt):
        watch(request, lambda f: flags.append((tick[0], f)), on_tick=on_tick, clock=clock, sleep=clock.sleep)
    got = [(k, f.joint, f.kind) for k, f in flags]
    assert got == [
        (10, "shoulder_pan", "step"),
        (30, "elbow_flex", "outside_stops"),
        (30, "elbow_flex", "step"),
    ]
    step = flags[0][1]
    assert math.degrees(step.value_rad) == pytest.approx(30 * 360 / 4096)
    past = flags[1][1]
    span_deg = (
        (TRUTH["elbow_flex"].stop_high_ticks - SHORT_TICKS - TRUTH["elbow_flex"].stop_low_ticks) * 360 / 4096
    )
    assert math.degrees(past.limit_rad) == pytest.approx(span_deg / 2 + 2.0)
    # read-only: the EEPROM, torque and goal registers as they were; the calibration file unchanged
    assert arm.eeprom() == eeprom
    assert {n: arm.servo(n).get_reg("Torque_Enable") for n in TRUTH} == torque
    assert {n: arm.servo(n).get_reg("Goal_Position") for n in TRUTH} == goal
    assert cal.read_bytes() == cal_bytes
    assert sorted(p.name for p in tmp_path.iterdir()) == ["follower.json"]


def test_watch_on_a_still_arm_prints_nothing_and_exits_0(
    arm: SimArm, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    cal = _calibration(tmp_path / "follower.json")
    args = ["health", "watch", "--lerobot-port", arm.port, "--robot", "so101_follower", "--file", str(cal)]
    rc = main([*args, "--seconds", "0.3", "--rate-hz", "50"])
    out, err = capsys.readouterr()
    assert rc == 0
    # the span is from the first to the last reading inside the 0.3 s (wall clock): on a loaded machine one read can
    # take longer than the 20 ms period, so the last one inside may come before 0.25 s ("over 0.2 s")
    said = re.fullmatch(r"watched 6 joints, (\d+) readings over (0\.\d) s: 0 flag\(s\)\n", out)
    assert said is not None, out
    assert int(said.group(1)) >= 1 and 0.0 <= float(said.group(2)) <= 0.3
    assert err.startswith(f"watching 6 joints of so101_follower on {arm.port} for 0.3 s: shoulder_pan, ")


@pytest.mark.parametrize(
    ("args", "message"),
    [
        ([], "error: give --lerobot-port PORT --robot ROBOT, or --source SOURCE (one of the two)"),
        (["--lerobot-port", "sim"], "error: --lerobot-port needs --robot (so101_follower, koch_leader, ...)"),
        (
            ["--lerobot-port", "sim", "--source", "sim:lite"],
            "error: give --lerobot-port PORT --robot ROBOT, or --source SOURCE (one of the two)",
        ),
        (
            ["--source", "sim:lite"],
            "error: --source needs --urdf (the joints' stops) and --calibration (the joint map)",
        ),
        (
            ["--lerobot-port", "sim", "--robot", "so101_follower", "--margin-deg", "-1"],
            "error: --margin-deg: expected a positive number, got -1.0",
        ),
        (
            ["--lerobot-port", "sim", "--robot", "so101_follower", "--seconds", "0"],
            "error: --seconds: expected a positive number, got 0.0",
        ),
        (["--lerobot-port", "sim", "--robot", "nosuch"], "error: unknown robot 'nosuch'; valid: "),
        (  # before: the pause between readings overflowed time.sleep, exit 70
            ["--lerobot-port", "sim", "--robot", "so101_follower", "--rate-hz", "1e-300"],
            "error: --rate-hz: expected at least 0.001 (one reading in 1000 s), got 1e-300",
        ),
    ],
)
def test_bad_options_are_one_error_line_and_exit_2(
    args: list[str], message: str, capsys: pytest.CaptureFixture[str]
) -> None:
    rc = main(["health", "watch", *args])
    out, err = capsys.readouterr()
    assert rc == 2 and out == ""
    assert err.startswith(message) and err.count("\n") == 1


def _lite_calibration(tmp_path: Path, seed: int, off_rad: dict[str, float]) -> tuple[Path, Path]:
    from robocal.backends.sim.lite import LITE_JOINTS, SimLite, lite_urdf_text

    urdf = tmp_path / "lite.urdf"
    urdf.write_text(lite_urdf_text())
    true = SimLite(seed).true_offsets()
    cal = tmp_path / "calibration.yaml"
    cal.write_text(
        "".join(
            f"{j.name}:\n  id: {j.can_id}\n  direction: {j.direction}\n"
            f"  homing_offset: {true[j.name] + off_rad.get(j.name, 0.0)!r}\n"
            for j in LITE_JOINTS
        )
    )
    return urdf, cal


@pytest.mark.slow
def test_watch_a_simulated_lite_flags_the_joint_whose_zero_is_off(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    urdf, cal = _lite_calibration(tmp_path, 3, {"left_elbow_pitch": 0.3})
    # the simulated operator turns at full speed at once (no hand does): a large acceleration limit
    args = ["--urdf", str(urdf), "--calibration", str(cal), "--seconds", "1.2", "--max-accel-deg-s2", "1e6"]
    rc = main(["health", "watch", "--source", "sim:lite?seed=3&noise=0", *args])
    out, _ = capsys.readouterr()
    assert rc == 1
    lines = out.splitlines()
    assert len(lines) == 2 and lines[-1].endswith(": 1 flag(s)")
    assert (
        "left_elbow_pitch: reading +" in lines[0] and "is past its stop (+2.00° with the margin)" in lines[0]
    )
    urdf, cal = _lite_calibration(tmp_path, 3, {})
    rc = main(["health", "watch", "--source", "sim:lite?seed=3&noise=0", *args])
    out, _ = capsys.readouterr()
    assert rc == 0 and out.rstrip().endswith(": 0 flag(s)")


@pytest.mark.slow
def test_watch_flags_a_robstride_reading_a_whole_turn_off_as_the_wrong_branch(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    urdf, cal = _lite_calibration(tmp_path, 3, {"right_wrist_yaw": 2 * math.pi})
    args = ["--urdf", str(urdf), "--calibration", str(cal), "--seconds", "0.2", "--max-accel-deg-s2", "1e6"]
    rc = main(["health", "watch", "--source", "sim:lite?seed=3&noise=0", *args])
    out, _ = capsys.readouterr()
    assert rc == 1
    lines = out.splitlines()
    assert lines[0].startswith("     0.000 s  right_wrist_yaw: reading ")
    assert lines[0].endswith("is on the wrong 2π branch (a whole turn off)")
    assert lines[-1].endswith(": 1 flag(s)")


def _leader_calibration(path: Path) -> Path:
    """The simulated leader's calibration: homing offset 0, ranges at its truth's stops (wrist_roll a full turn)."""
    truth = DEFAULT_TRUTH["so101_leader"]
    cals = {
        name: {
            "id": i + 1,
            "drive_mode": 0,
            "homing_offset": 0,
            "range_min": 0 if name == "wrist_roll" else int(t.stop_low_ticks),
            "range_max": 4095 if name == "wrist_roll" else int(t.stop_high_ticks),
        }
        for i, (name, t) in enumerate(truth.items())
    }
    path.write_text(json.dumps(cals, indent=4))
    return path


def test_a_follower_held_while_its_leader_goes_on_is_flagged_pinned(arm: SimArm, tmp_path: Path) -> None:
    cal = _calibration(tmp_path / "follower.json")
    lcal = _leader_calibration(tmp_path / "leader.json")
    with SimArm(robot_spec("so101_leader"), transport="inproc") as leader:
        mid = DEFAULT_TRUTH["so101_leader"]["elbow_flex"].mid_ticks
        flags: list[tuple[int, HealthFlag]] = []
        tick = [0]
        eeprom = leader.eeprom()

        def on_tick(k: int) -> None:
            tick[0] = k
            if (
                10 <= k < 50
            ):  # the leader's elbow goes on, 5 counts a tick, 200 in all (17.6°); the follower stays
                leader.move({"elbow_flex": mid + 5 * (k - 9)})
            if k == 120:
                raise KeyboardInterrupt

        clock = FakeClock()
        request = WatchRequest(
            lerobot_port=arm.port,
            robot="so101_follower",
            calibration_file=cal,
            leader_port=leader.port,
            leader_robot="so101_leader",
            leader_file=lcal,
        )
        with pytest.raises(KeyboardInterrupt):
            watch(
                request, lambda f: flags.append((tick[0], f)), on_tick=on_tick, clock=clock, sleep=clock.sleep
            )
        assert leader.eeprom() == eeprom
    assert [(f.joint, f.kind) for _, f in flags] == [("elbow_flex", "pinned")]
    k, flag = flags[0]
    # both read +25 counts at rest: more than 5° (57 counts) apart from tick 21 on; 0.3 s later, at a 50 ms check
    assert 21 + 30 <= k <= 21 + 30 + 6
    assert math.degrees(flag.value_rad) > 5.0


def test_leader_options_without_a_leader_port_are_refused(capsys: pytest.CaptureFixture[str]) -> None:
    rc = main(["health", "watch", "--lerobot-port", "sim", "--robot", "so101_follower", "--leader-id", "x"])
    _, err = capsys.readouterr()
    assert rc == 2
    assert err == "error: --leader-robot, --leader-id and --leader-file go with --leader-port\n"


@pytest.mark.parametrize("option", ["--file", "--leader-file"])
def test_a_calibration_file_without_every_motor_is_named_in_the_error(
    option: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """Before: "calibration has no entry for motor(s) gripper", which of the two files not said."""
    good = _calibration(tmp_path / "follower.json")
    partial = tmp_path / "partial.json"
    partial.write_text(json.dumps({k: v for k, v in json.loads(good.read_text()).items() if k != "gripper"}))
    files = {"--file": good, "--leader-file": good, option: partial}
    rc = main(["health", "watch", "--lerobot-port", "sim", "--robot", "so101_follower", "--file", str(files["--file"]),
               "--leader-port", "sim", "--leader-robot", "so101_follower", "--leader-file", str(files["--leader-file"]),
               "--seconds", "0.1"])  # fmt: skip
    out, err = capsys.readouterr()
    assert rc == 2 and out == ""
    assert err == f"error: calibration {partial} has no entry for motor(s) gripper\n"


def test_a_simulated_port_for_a_profile_file_names_the_arms_it_simulates(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """Before: "no simulated truth for robot 'myarm'; pass truth=", an argument of the Python class, on the CLI;
    then "... (from Python, pass truth=)"; now the flag, the arms the simulator has and what to give instead."""
    shipped = Path(__file__).parents[2] / "src/robocal/data/profiles/so101_follower.yaml"
    profile = tmp_path / "myarm.yaml"
    profile.write_text(re.sub(r"(?m)^name: .*$", "name: myarm", shipped.read_text()))
    cal = _calibration(tmp_path / "follower.json")
    rc = main(["health", "watch", "--lerobot-port", "sim", "--robot", str(profile), "--file", str(cal),
               "--seconds", "0.1"])  # fmt: skip
    out, err = capsys.readouterr()
    assert rc == 2 and out == ""
    assert err == (
        "error: --lerobot-port 'sim': the simulator has the built-in arms only (koch_follower, koch_leader, "
        "so100_follower, so100_leader, so101_follower, so101_leader); robot 'myarm' (a profile file) is not one of "
        "them: give one of those to --robot, or the real arm's port\n"
    )


def test_seconds_ends_the_watch_at_a_slow_rate_without_waiting_a_whole_period(arm: SimArm, tmp_path: Path) -> None:
    """``--seconds 1 --rate-hz 0.01`` slept 100 s (the loop paused a whole period before it looked at the time);
    the pause now ends at the deadline."""
    cal = _calibration(tmp_path / "follower.json")
    clock = FakeClock()
    pauses: list[float] = []

    def sleep(dt: float) -> None:
        pauses.append(dt)
        clock.sleep(dt)

    request = WatchRequest(lerobot_port=arm.port, robot="so101_follower", calibration_file=cal, seconds=1.0, rate_hz=0.01)
    result = watch(request, lambda f: None, clock=clock, sleep=sleep)
    assert result.ticks == 1 and pauses and max(pauses) < 1.01
