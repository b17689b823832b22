"""``robocal dataset health`` on simulated LeRobot v3 teleoperation datasets with a known truth (issue 30 item 1).

The refusals run in the fast tier; a whole check with its picture takes seconds on a loaded machine (slow).
"""

from __future__ import annotations

import json
import math
import os
from pathlib import Path

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from tests.parquet import reads_null_list_rows

from robocal.backends.sim.teleop import TELEOP_ARMS, TeleopFaults, TeleopSession, simulate_sessions
from robocal.cli.main import main
from robocal.dataset.teleop_sim import generate_teleop_datasets, write_teleop_dataset
from robocal.lerobot import MotorCalibration, write_calibration


def run(capsys: pytest.CaptureFixture[str], *args: object) -> tuple[int, str, str]:
    code = main([str(a) for a in args])
    out, err = capsys.readouterr()
    return code, out, err


@pytest.fixture(scope="module")
def roots(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    d = tmp_path_factory.mktemp("health")
    so = generate_teleop_datasets(
        d,
        "so101",
        [22, 21, 23],
        [
            TeleopFaults(offset_joint="elbow_flex", offset_deg=-17.0),
            TeleopFaults(),
            TeleopFaults(slip_joint="wrist_flex", slip_episode=1, slip_frame=100, slip_deg=9.0),
        ],
        episodes=3,
        episode_s=8.0,
        p_end=1.0,
    )
    koch = generate_teleop_datasets(
        d / "koch",
        "koch",
        [25],
        [TeleopFaults(offset_joint="elbow_flex", offset_deg=17.0)],
        use_degrees=False,
        episodes=3,
        episode_s=8.0,
        p_end=1.0,
    )
    return {"offset": so[0], "clean": so[1], "slip": so[2], "koch": koch[0], "dir": d}


def _truth(root: Path) -> dict[str, object]:
    out: dict[str, object] = json.loads(root.with_name(root.name + ".truth.json").read_text())
    return out


@pytest.mark.slow
def test_17_degree_offset_flagged_and_named(
    roots: dict[str, Path], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    report = tmp_path / "health.json"
    code, out, err = run(capsys, "dataset", "health", roots["offset"], "--report", report)
    assert code == 1
    data = json.loads(report.read_text())
    joint = data["joints"]["elbow_flex"]
    # the SO-101 follower is held by its position limits: a follower-side offset holds both ends alike, so the
    # joint is named with the size of the disagreement and no sign (an offset with a sign needs the stops pressed)
    assert (joint["status"], joint["offset_deg"], joint["ci_deg"]) == ("suspect", None, None)
    assert any("held by its position limit" in r for r in joint["reasons"]), joint["reasons"]
    assert data["flagged"] == ["elbow_flex"]
    assert set(joint) >= {"offset_deg", "ci_deg", "status", "episodes"}
    assert [e["episode"] for e in joint["episodes"]] == [0, 1, 2]
    assert "elbow_flex" in out and "suspect" in out
    assert err.count("warning:") == 1 and "elbow_flex: suspect" in err
    png = report.with_suffix(".png").read_bytes()
    assert png[:8] == b"\x89PNG\r\n\x1a\n"


@pytest.mark.slow
def test_offset_free_dataset_exits_0(
    roots: dict[str, Path], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    report = tmp_path / "h.json"
    code, _, err = run(capsys, "dataset", "health", roots["clean"], "--report", report)
    assert code == 0, err
    statuses = {j["status"] for j in json.loads(report.read_text())["joints"].values()}
    assert statuses <= {"ok", "unobservable"}


@pytest.mark.slow
def test_slip_located_to_its_episode(
    roots: dict[str, Path], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    report = tmp_path / "h.json"
    code, _, _ = run(capsys, "dataset", "health", roots["slip"], "--report", report)
    assert code == 1
    joint = json.loads(report.read_text())["joints"]["wrist_flex"]
    assert joint["status"] == "suspect"
    assert [(j["episode"], abs(j["frame"] - 100) <= 2) for j in joint["jumps"]] == [(1, True)]
    assert [len(e["jumps"]) for e in joint["episodes"]] == [0, 1, 0]


@pytest.mark.slow
def test_range_modes_clamp_like_lerobot_so_a_leader_offset_never_presses_the_follower(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """LeRobot clamps a range-mode value to the calibrated range on reading an arm and on making the goal. Before,
    the simulator wrote a −17° leader offset as values down to −117 and drove the follower 17° into its stop, which no
    LeRobot session does, and the check found the offset from that. Clamped, the follower's goal never passes its
    stop: the offset is `unobservable` in range_m100_100 (in degrees the same session presses and is flagged)."""
    fault = TeleopFaults(offset_joint="elbow_flex", offset_deg=-17.0, offset_arm="leader")
    kw = {"episodes": 3, "episode_s": 8.0, "p_end": 1.0}
    (ranged,) = generate_teleop_datasets(tmp_path / "range", "koch", [25], [fault], use_degrees=False, **kw)
    (degrees,) = generate_teleop_datasets(tmp_path / "deg", "koch", [25], [fault], use_degrees=True, **kw)
    table = pq.read_table(ranged / "data/chunk-000/file-000.parquet")
    action = np.asarray(table.column("action").to_pylist())
    state = np.asarray(table.column("observation.state").to_pylist())
    k = TELEOP_ARMS["koch"].joints.index("elbow_flex")
    assert action[:, k].min() == pytest.approx(-100.0, abs=1e-4) and np.abs(action).max() <= 100.0 + 1e-4
    assert np.abs(state).max() <= 100.0 + 1e-4 and state[:, -1].min() >= 0.0  # gripper range_0_100
    assert _truth(ranged)["joints"]["elbow_flex"]["pin_depth_deg"] == 0.0  # type: ignore[index]
    assert _truth(degrees)["joints"]["elbow_flex"]["pin_depth_deg"] > 10.0  # type: ignore[index]
    report = tmp_path / "h.json"
    run(capsys, "dataset", "health", ranged, "--report", report)
    assert json.loads(report.read_text())["joints"]["elbow_flex"]["status"] == "unobservable"
    code, _, _ = run(capsys, "dataset", "health", degrees, "--report", report, "--use-degrees")
    joint = json.loads(report.read_text())["joints"]["elbow_flex"]
    lo, hi = joint["ci_deg"]  # offset = follower − leader = +17°
    assert (code, joint["status"]) == (1, "offset") and lo - 0.5 <= 17.0 <= hi + 0.5, joint["ci_deg"]


def test_an_so101_follower_limit_holds_the_goal_where_the_range_was_recorded(tmp_path: Path) -> None:
    """LeRobot writes the recorded range into the STS3215's Min/Max_Position_Limit, which clamp its goal: with
    ``goal_limits`` the follower stands at its limit (its hand scatter and |offset| inside the stop, in its own
    reading frame) while the leader goes on, and is never driven into the stop."""
    from robocal.backends.sim.teleop import goal_limits_deg, hand_scatter_deg

    arm = TELEOP_ARMS["so101"]
    fault = TeleopFaults(offset_joint="elbow_flex", offset_deg=-17.0, offset_arm="follower")
    free, limited = (simulate_sessions(arm, [26], [fault], episodes=3, episode_s=8.0, p_end=1.0, goal_limits=g)[0]
                     for g in (False, True))  # fmt: skip
    k = arm.joints.index("elbow_flex")
    x = hand_scatter_deg(arm, 26)[1]
    lo, hi = goal_limits_deg(arm, np.eye(6)[k] * -17.0, x, arm.modes)
    assert (lo[k], hi[k]) == pytest.approx((-96.83 + x[k] + 17.0, 96.83 - x[k] - 17.0))
    assert lo[4] == -np.inf and hi[5] == 115.0  # wrist_roll recorded as a full turn; the gripper at its stops
    t_free, t_lim = free.truth["elbow_flex"], limited.truth["elbow_flex"]
    assert t_free.pin_depth_deg > 15.0 and t_lim.pin_depth_deg == 0.0  # the goal never passes the stop
    assert t_lim.limited_lo_deg > 15.0 or t_lim.limited_hi_deg > 15.0
    assert limited.state_deg[..., k].min() >= lo[k] - 1.0 and limited.state_deg[..., k].max() <= hi[k] + 1.0
    assert TELEOP_ARMS["koch"].goal_limited is False  # Dynamixels in extended position mode do not enforce them


@pytest.mark.slow
def test_an_offset_free_so101_pair_whose_follower_enforces_its_limits_is_not_flagged(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """A follower range recorded up to 1.5° inside its stops holds the follower up to 1.5° short of its leader at
    both ends; before the check read held ends as limits, that was two ends that disagree (exit 1)."""
    (root,) = generate_teleop_datasets(tmp_path, "so101", [21], [TeleopFaults()], episodes=3, episode_s=8.0,
                                       p_end=1.0, goal_limits=True)  # fmt: skip
    code, _, err = run(capsys, "dataset", "health", root, "--report", tmp_path / "h.json")
    assert code == 0, err


def _koch_calibration(path: Path, widen_deg: float = 0.0) -> None:
    arm = TELEOP_ARMS["koch"]
    cals = {}
    for i, name in enumerate(arm.joints):
        lo, hi = arm.stop_lo_deg[i], arm.stop_hi_deg[i]
        if not math.isfinite(lo):
            rmin, rmax = 0, 4095
        else:
            lo, hi = lo - widen_deg / 2, hi + widen_deg / 2
            rmin, rmax = round(2048 + lo * 4096 / 360), round(2048 + hi * 4096 / 360)
        cals[name] = MotorCalibration(i + 1, 0, 0, rmin, rmax)
    write_calibration(path, cals)


@pytest.mark.slow
def test_range_units_without_files_and_degrees_with_them(
    roots: dict[str, Path], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    plain = tmp_path / "plain.json"
    code, _, _ = run(capsys, "dataset", "health", roots["koch"], "--report", plain)
    joint = json.loads(plain.read_text())["joints"]["elbow_flex"]
    assert code == 1
    assert (joint["units"], joint["offset_deg"], joint["status"]) == ("range_m100_100", None, "offset")
    assert joint["offset"] == pytest.approx(17.0 / 96.7 * 100, abs=4.0)
    _koch_calibration(tmp_path / "cal.json")
    report = tmp_path / "deg.json"
    code, _, err = run(
        capsys,
        "dataset",
        "health",
        roots["koch"],
        "--report",
        report,
        "--leader-calibration",
        tmp_path / "cal.json",
        "--follower-calibration",
        tmp_path / "cal.json",
    )
    assert code == 1, err
    joint = json.loads(report.read_text())["joints"]["elbow_flex"]
    assert (joint["units"], joint["status"]) == ("degrees", "offset")
    assert joint["offset_deg"] == pytest.approx(17.0, abs=3.0)
    # a leader file whose recorded ranges are 12° wider than the follower's: every joint with stops is suspect
    _koch_calibration(tmp_path / "wide.json", widen_deg=12.0)
    code, _, _ = run(capsys, "dataset", "health", roots["koch"], "--report", report,
                     "--leader-calibration", tmp_path / "wide.json", "--follower-calibration", tmp_path / "cal.json")
    joints = json.loads(report.read_text())["joints"]
    assert code == 1
    assert joints["wrist_flex"]["status"] == "suspect"
    assert (
        "recorded ranges differ: leader 206.7°, follower 194.8° (calibration files; the profile's stops span 194.8°): "
        "a range recorded 12.0° short at one end moves that arm's zero by up to ±6.0°"
    ) in joints["wrist_flex"]["reasons"]


def _write(session: TeleopSession, root: Path) -> Path:
    write_teleop_dataset(session, root)
    return root


@pytest.fixture(scope="module")
def small(tmp_path_factory: pytest.TempPathFactory) -> TeleopSession:
    return simulate_sessions(TELEOP_ARMS["so101"], [5], [TeleopFaults()], episodes=1, episode_s=2.0)[0]


def _bad_case(kind: str, small: TeleopSession, root: Path) -> None:
    if kind == "constant":
        flat = np.zeros_like(small.action_deg)
        _write(TeleopSession(small.arm, small.fps, flat, flat, small.faults), root)
    elif kind == "one frame":
        _write(
            TeleopSession(
                small.arm, small.fps, small.action_deg[:, :1], small.state_deg[:, :1], small.faults
            ),
            root,
        )
    elif kind == "nan":
        state = small.state_deg.copy()
        state[0, 5, 2] = np.nan
        _write(TeleopSession(small.arm, small.fps, small.action_deg, state, small.faults), root)
    elif kind == "missing column":
        _write(small, root)
        path = root / "data/chunk-000/file-000.parquet"
        pq.write_table(pq.read_table(path).drop(["action"]), path)
    elif kind == "missing feature":
        _write(small, root)
        info = json.loads((root / "meta/info.json").read_text())
        del info["features"]["observation.state"]
        (root / "meta/info.json").write_text(json.dumps(info))
    elif kind in ("one calibration", "robot bhl_arms", "urdf of another arm", "robot empty"):
        _write(small, root)
    elif kind == "robot_type so100":
        _write(small, root)
        info = json.loads((root / "meta/info.json").read_text())
        info["robot_type"] = "so100"  # LeRobot v2-era datasets, converted to v3, keep it
        (root / "meta/info.json").write_text(json.dumps(info))
    elif kind == "root is a file":
        root.write_text("not a dataset\n")
    elif kind == "info.json a folder":
        _write(small, root)
        (root / "meta/info.json").unlink()
        (root / "meta/info.json").mkdir()
    elif kind == "another arm's joints":
        _write(small, root)
        info = json.loads((root / "meta/info.json").read_text())
        for key in ("action", "observation.state"):
            info["features"][key]["names"] = [f"arm_{n}" for n in info["features"][key]["names"]]  # LeKiwi's
        (root / "meta/info.json").write_text(json.dumps(info))
    elif kind == "duplicate names":
        _write(small, root)
        info = json.loads((root / "meta/info.json").read_text())
        for key in ("action", "observation.state"):
            info["features"][key]["names"][1] = "shoulder_pan.pos"
        (root / "meta/info.json").write_text(json.dumps(info))
    elif kind == "fifo":
        _write(small, root)
        path = root / "data/chunk-000/file-000.parquet"
        path.unlink()
        os.mkfifo(path)
    elif kind == "file copied":
        _write(small, root)
        path = root / "data/chunk-000/file-000.parquet"
        path.with_name("file-001.parquet").write_bytes(path.read_bytes())
    elif kind in ("null row", "null episode", "float episode"):
        _write(small, root)
        path = root / "data/chunk-000/file-000.parquet"
        table = pq.read_table(path)
        key = "observation.state" if kind == "null row" else "episode_index"
        col = table.column(key).to_pylist()
        col[3] = None
        typ = table.schema.field(key).type
        if kind == "float episode":
            col, typ = [i + 0.5 for i in table.column(key).to_pylist()], pa.float64()
        pq.write_table(table.set_column(table.schema.get_field_index(key), key, pa.array(col, typ)), path)


@pytest.mark.parametrize(
    "kind, needle",
    [
        ("constant", "no joint moves"),
        ("one frame", "fewer than 2 frames"),
        ("nan", "NaN or infinite"),
        ("missing column", "missing column(s) action"),
        ("missing feature", "unknown feature 'observation.state'"),
        ("one calibration", "go together"),
        # before: an IndexError (exit 70), the null row dropped from one column only
        (
            "null row",
            "column 'observation.state' has null rows (frames with no value)"
            if reads_null_list_rows()
            else "cannot read Parquet (Expected all lists to be of size=6",
        ),
        # before: numpy's "invalid value encountered in cast" warning on stderr and exit 0
        ("null episode", "column 'episode_index' is int64 with null rows; expected an integer episode number"),
        ("float episode", "column 'episode_index' is double; expected an integer episode number"),
        # before: exit 1, a "step" on every joint where the copy starts the session again
        ("file copied", "frame 0 of episode 0 is recorded 2 times ("),
        # before: the reader waited for ever on the FIFO
        ("fifo", "ds: data/chunk-000/file-000.parquet is not a regular file"),
        # before: exit 0 and a report keyed by name that kept one of the two shoulder_pan columns
        ("duplicate names", "action and observation.state name shoulder_pan more than once"),
        # before: "no such folder" and "missing meta/info.json" for paths that exist
        ("root is a file", "ds: not a folder"),
        ("info.json a folder", "ds: meta/info.json is not a file (is this a LeRobot v3 dataset?)"),
        # before: exit 0, every joint "unobservable" for "no range-end contact" (the profile has no stops for them)
        ("another arm's joints", "observation.state names arm_shoulder_pan, arm_shoulder_lift, arm_elbow_flex, "
         "arm_wrist_flex, arm_wrist_roll, arm_gripper, none of them a joint of so101_follower (shoulder_pan, "),
        # before: "--robot 'so100': not a built-in robot ... and not a profile file", with no --robot given (and a
        # robot_type naming a file on disk was read as a profile)
        ("robot_type so100", "meta/info.json robot_type 'so100' is not a built-in LeRobot arm (koch_follower, "),
        # before: "--robot 'bhl_arms': unknown robot type; known: so*, koch*, lekiwi* (or pass --motor-family)", an
        # option dataset health does not have; a profile file the same
        ("robot bhl_arms", "--robot 'bhl_arms': dataset health needs a built-in LeRobot arm (koch_follower, koch_"),
        # before: exit 0, the empty --robot replaced by meta/info.json's robot_type without a word
        ("robot empty", "--robot '' is empty: name a built-in LeRobot arm (koch_follower, koch_leader, "),
        # before: exit 0, no sag subtracted on any joint (not even the fitted one), the report naming the URDF's masses
        ("urdf of another arm", "other.urdf: none of the dataset's joints (shoulder_pan, shoulder_lift, elbow_flex,"),
    ],
)
def test_degenerate_dataset_exits_2_with_one_error_line(
    kind: str, needle: str, small: TeleopSession, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    root = tmp_path / "ds"
    _bad_case(kind, small, root)
    report = tmp_path / "h.json"
    extra = ["--leader-calibration", tmp_path / "x.json"] if kind == "one calibration" else []
    extra += ["--robot", "bhl_arms"] if kind == "robot bhl_arms" else []
    extra += ["--robot", ""] if kind == "robot empty" else []
    if kind == "urdf of another arm":  # the SO-101's URDF with every joint renamed: masses, no joint of the dataset
        urdf = tmp_path / "other.urdf"
        shipped = Path(__file__).parents[2] / "src/robocal/data/so101_new_calib.urdf"
        urdf.write_text(shipped.read_text().replace('joint name="', 'joint name="other_'))
        extra += ["--urdf", urdf]
    code, _, err = run(capsys, "dataset", "health", root, "--report", report, *extra)
    assert code == 2
    lines = [ln for ln in err.splitlines() if ln.strip()]
    assert len(lines) == 1 and lines[0].startswith("error:") and needle in lines[0], err
    assert not report.exists() and not report.with_suffix(".png").exists()


def test_values_no_lerobot_arm_records_flag_the_joint_with_no_offset(
    small: TeleopSession, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """Before, a leader column scaled by 1e30 (a corrupted value, another unit) was ``unobservable`` with a "model
    band" of 1.9e31° and exit 0: nothing flagged on numbers that are no reading of the joint."""
    action, state = small.action_deg.copy(), small.state_deg.copy()
    action[0, :, 0] *= 1e30  # (episode, frame, joint): shoulder_pan's leader
    state[0, 7, 3] = 400.0  # one follower frame of wrist_flex beyond a turn
    root = _write(TeleopSession(small.arm, small.fps, action, state, small.faults), tmp_path / "ds")
    report = tmp_path / "h.json"
    code, _, err = run(capsys, "dataset", "health", root, "--robot", "so101_follower", "--report", report)
    assert code == 1
    joints = json.loads(report.read_text())["joints"]
    pan, wrist = joints["shoulder_pan"], joints["wrist_flex"]
    assert (pan["status"], pan["offset_deg"], pan["ci_deg"]) == ("suspect", None, None)
    assert pan["reasons"][0].startswith("action (the leader) reads ") and "60 frame(s) outside -360..360" in pan[
        "reasons"][0]  # fmt: skip
    assert (wrist["status"], wrist["offset_deg"]) == ("suspect", None)
    assert wrist["reasons"][0].startswith("observation.state (the follower) reads 400 in frame 7 (episode 0), 1 frame")
    assert {n for n, j in joints.items() if j["status"] == "suspect"} == {"shoulder_pan", "wrist_flex"}
    assert "shoulder_pan: suspect: action (the leader) reads" in err


def test_report_must_be_json(
    small: TeleopSession, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    root = _write(small, tmp_path / "ds")
    code, _, err = run(capsys, "dataset", "health", root, "--report", tmp_path / "h.txt")
    assert code == 2 and "expected a .json file" in err


@pytest.mark.slow
@pytest.mark.timeout(900)  # six simulated sessions: ~35 s on a quiet machine, over 120 s at load 20
@settings(max_examples=6, deadline=None, derandomize=True)
@given(
    size=st.sampled_from([5.0, 8.0, 17.0]),
    sign=st.sampled_from([-1.0, 1.0]),
    joint=st.sampled_from(["shoulder_lift", "elbow_flex", "wrist_flex"]),
    arm=st.sampled_from(["leader", "follower"]),
    seed=st.integers(0, 10_000),
)
def test_contact_offsets_are_flagged_with_the_truth_in_the_interval(
    size: float, sign: float, joint: str, arm: str, seed: int
) -> None:
    """Every session whose follower was pressed against a stop: ``offset`` on the right joint, truth inside."""
    from robocal.core.health import JointData, analyse_joint, sag_residual_deg
    from robocal.dataset.teleop_sim import arm_gravity
    from robocal.formats.urdf_gravity import gravity_model_from_urdf

    a = TELEOP_ARMS["so101"]
    s = simulate_sessions(
        a,
        [seed],
        [TeleopFaults(offset_joint=joint, offset_deg=sign * size, offset_arm=arm)],
        gravity=arm_gravity(a),
        episodes=3,
        episode_s=8.0,
        p_end=1.0,
    )[0]
    truth = s.truth[joint]
    k = a.joints.index(joint)
    e, t, n = s.action_deg.shape
    state = s.state_deg.reshape(-1, n)
    model = gravity_model_from_urdf(Path(__file__).parents[2] / "src/robocal/data/so101_new_calib.urdf")
    sag = sag_residual_deg(model, a.joints, state, a.kp_nm_rad)[:, k]
    d = JointData(
        joint,
        s.action_deg.reshape(-1, n)[:, k],
        state[:, k],
        np.repeat(np.arange(e), t),
        sag,
        a.stop_lo_deg[k],
        a.stop_hi_deg[k],
    )
    h = analyse_joint(d)
    if truth.pin_depth_deg > 3.0:
        # pressed well into a stop: flagged with the right sign; a contact measures at most the whole offset
        assert h.status == "offset"
        assert h.offset is not None and h.ci is not None
        assert np.sign(h.offset) == np.sign(truth.offset_deg)
        assert abs(h.offset) <= abs(truth.offset_deg) + 1.0
    else:
        assert h.status != "ok" or abs(truth.offset_deg) <= 3.0


@pytest.mark.slow
def test_arrow_tables_are_read_in_episode_order(roots: dict[str, Path]) -> None:
    from robocal.dataset.health import read_teleop_frames

    fr = read_teleop_frames(roots["clean"])
    assert list(np.unique(fr.episode)) == [0, 1, 2]
    assert fr.action.shape == (3 * 240, 6)
    table = pq.read_table(roots["clean"] / "data/chunk-000/file-000.parquet")
    assert table.schema.field("action").type == pa.list_(pa.float32(), 6)


@pytest.mark.slow
def test_many_datasets_through_datatrove(small: TeleopSession, tmp_path: Path) -> None:
    """One report per root; a root the check refuses gets its error line instead of stopping the others."""
    from robocal.workflows.dataset.health_cluster import health_with_datatrove

    good = _write(small, tmp_path / "good")
    bad = tmp_path / "bad"
    _bad_case("nan", small, bad)
    paths = health_with_datatrove([good, bad], tmp_path / "out", tasks=2, workers=1)
    reports = [json.loads(p.read_text()) for p in paths]
    assert [p.name for p in paths] == ["good.health.json", "bad.health.json"]
    assert set(reports[0]["joints"]) == set(TELEOP_ARMS["so101"].joints)
    assert "NaN or infinite" in reports[1]["error"]


@pytest.mark.parametrize("link", ["h.png", "h.json"])
def test_a_picture_that_is_the_report_through_a_link_is_refused(
    link: str, small: TeleopSession, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """Before, ``h.png`` a link to ``h.json``: the report was written, then the picture replaced it through the
    link: exit 0, ``h.json`` a PNG and the JSON in ``h.json.bak`` (``h.json`` a link to ``h.png``: the JSON went
    into ``h.png`` and the picture replaced it)."""
    root = _write(small, tmp_path / "ds")
    out = tmp_path / "out"
    out.mkdir()
    report = out / "h.json"
    other = "h.json" if link == "h.png" else "h.png"
    (out / other).write_text("{}\n")
    (out / link).symlink_to(out / other)
    code, _, err = run(capsys, "dataset", "health", root, "--report", report)
    assert code == 2
    assert err == (
        f"error: the report's picture {out / 'h.png'}: is --report ({report}); give the output its own path\n"
    )
    assert sorted(p.name for p in out.iterdir()) == ["h.json", "h.png"]
    assert (out / other).read_text() == "{}\n" and (out / link).is_symlink()


def test_a_urdf_without_masses_is_said_not_dropped_silently(
    small: TeleopSession, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """Before, ``--urdf koch.urdf`` (no masses) on an SO-101 dataset was not used and only the report's
    ``"urdf": null`` said so (exit 0)."""
    root = _write(small, tmp_path / "ds")
    urdf = Path(__file__).parents[2] / "src/robocal/data/koch.urdf"
    report = tmp_path / "h.json"
    code, _, err = run(capsys, "dataset", "health", root, "--report", report, "--urdf", urdf)
    assert code == 0 and json.loads(report.read_text())["model"]["urdf"] is None
    assert f"warning: --urdf {urdf}: no link masses; the sag was fitted from the data instead" in err
