"""`robocal view` end to end: the simulated Lite, a replay through a calibration, bad input, Ctrl-C."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("viser")  # robocal[view]; installed by the [test] extra
pytest.importorskip("yourdfpy")
pytest.importorskip("trimesh")

from tests.bags import write_joint_states
from tests.net import busy_port

from robocal.cli.main import main
from robocal.errors import JointMismatchError
from robocal.formats import read_calibration
from robocal.formats.urdf import read_urdf
from robocal.viewer.session import ViewOptions, open_view

from .conftest import LITE_URDF, REPO, serve_then_ctrl_c, wait_for

LITE_CAL = REPO / "examples" / "lite" / "calibration.yaml"


def test_sim_lite_through_a_calibration_with_the_uncalibrated_ghost() -> None:
    opts = ViewOptions(urdf=LITE_URDF, source="sim:lite?seed=3", calibration=LITE_CAL, compare="none", port=0)
    cal = read_calibration(LITE_CAL, urdf=read_urdf(LITE_URDF)).calibration
    with open_view(opts) as session:
        app = session.app
        seen: list[np.ndarray] = []

        def moved() -> bool:
            u = app.last_update
            if u is not None and (not seen or not np.array_equal(seen[-1], u.q)):
                seen.append(u.q.copy())
            return len(seen) >= 3

        wait_for(moved)
        u = app.last_update
        assert u is not None and u.q_compare is not None
        names = list(app.joint_names)
        assert len(names) == 14
        raw = u.frame.raw
        np.testing.assert_allclose(u.q, cal.select(names).to_joint(raw), atol=1e-12)
        np.testing.assert_allclose(u.q_compare, cal.select(names).direction * raw, atol=1e-12)
        status = app.status()
        assert status["calibration"] == "calibration.yaml" and status["source"] == "running"
        assert status["compare"] == "none (direction·raw)"
    assert app.server is None and not session.feed.alive


def write_csv(path: Path, names: list[str], rows: list[list[float]]) -> None:
    path.write_text(
        "t," + ",".join(names) + "\n" + "".join(",".join(repr(x) for x in r) + "\n" for r in rows)
    )


def test_replay_csv_through_a_calibration(tmp_path: Path) -> None:
    cal = read_calibration(LITE_CAL, urdf=read_urdf(LITE_URDF)).calibration
    rec = tmp_path / "rec.csv"
    write_csv(rec, ["left_elbow_pitch", "left_shoulder_pitch"], [[0.0, -1.0, -0.5], [1.0, -0.8, -0.3]])
    opts = ViewOptions(urdf=LITE_URDF, source=f"replay:{rec}", calibration=LITE_CAL, port=0)
    with open_view(opts) as session:
        feed = session.feed
        feed.pause()  # type: ignore[attr-defined]
        feed.seek(1.0)  # type: ignore[attr-defined]
        wait_for(lambda: session.app.last_update is not None and session.app.last_update.frame.t_s == 1.0)
        joints = {j["name"]: j for j in session.app.status()["joints"]}
    # identity-frame values x: raw = d·x, q = d·(raw − h) = x − d·h
    for name, x in (("left_elbow_pitch", -0.8), ("left_shoulder_pitch", -0.3)):
        jm = cal.joint_map(name)
        assert joints[name]["q"] == pytest.approx(x - jm.direction * jm.homing_offset, abs=1e-12)
        assert joints[name]["raw"] == pytest.approx(jm.direction * x, abs=1e-12)
    assert joints["right_elbow_pitch"]["raw"] is None  # no column: no reading
    assert session.app.status()["replay"]["end_s"] == 1.0


def test_calibration_of_another_robot_is_refused(tmp_path: Path) -> None:
    other = tmp_path / "other.yaml"
    other.write_text("joint_a:\n  id: 1\n  direction: 1\n  homing_offset: 0.0\n")
    opts = ViewOptions(urdf=LITE_URDF, source="sim:lite", calibration=other, port=0)
    with pytest.raises(JointMismatchError, match="none of its joints"):
        open_view(opts)


def run_cli(args: list[str], capsys: pytest.CaptureFixture[str]) -> tuple[int, str, str]:
    code = main(args)
    out, err = capsys.readouterr()
    return code, out, err


def test_cli_bad_urdf_one_error_line_nothing_written(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    bad = tmp_path / "bad.urdf"
    bad.write_text("<robot name='x'><link name='a'/>")
    before = sorted(tmp_path.iterdir())
    code, _, err = run_cli(["view", "--urdf", str(bad), "--source", "sim:lite", "--port", "0"], capsys)
    assert code == 2
    lines = err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: ") and "bad.urdf" in lines[0]
    assert sorted(tmp_path.iterdir()) == before


@pytest.mark.parametrize(
    ("extra", "needle"),
    [
        ([], "give exactly one of --source, --lerobot-port or --ur-host"),
        (["--source", "sim:lite", "--ur-host", "10.0.0.2"], "(got --source, --ur-host)"),
        (["--source", "bogus"], "--source 'bogus'"),
        (["--source", "sim:lite", "--frame", "motor"], "--frame goes with --source replay:FILE"),
        (["--lerobot-port", "sim"], "--lerobot-port needs --robot"),
        (["--source", "sim:lite", "--package-path", "nope"], "expected NAME=DIR"),
        (["--source", "replay:/nonexistent/rec.csv"], "no such file"),
    ],
)
def test_cli_usage_errors(extra: list[str], needle: str, capsys: pytest.CaptureFixture[str]) -> None:
    code, _, err = run_cli(["view", "--urdf", str(LITE_URDF), "--port", "0", *extra], capsys)
    assert code == 2
    assert err.count("\n") == 1 and err.startswith("error: ") and needle in err


def test_cli_port_in_use(capsys: pytest.CaptureFixture[str]) -> None:
    with busy_port() as port:
        code, _, err = run_cli(
            ["view", "--urdf", str(LITE_URDF), "--source", "sim:lite", "--port", str(port)], capsys
        )
    assert code == 2
    assert (
        err
        == f"error: port {port} on 127.0.0.1 is in use by another program; pass --port with a free one (or --port 0 for any)\n"
    )


@pytest.mark.slow
def test_cli_replay_for_a_duration(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    rec = tmp_path / "rec.csv"
    write_csv(rec, ["left_elbow_pitch"], [[0.0, -1.0], [0.5, -0.5]])
    code, out, err = run_cli(
        ["view", "--urdf", str(LITE_URDF), "--source", f"replay:{rec}", "--port", "0", "--duration", "0.5"],
        capsys,
    )
    assert code == 0 and err == ""
    assert out.startswith("robocal view: serving http://127.0.0.1:") and out.rstrip().endswith(
        "(Ctrl-C to stop)"
    )
    assert sorted(p.name for p in tmp_path.iterdir()) == ["rec.csv"]


@pytest.mark.slow
def test_ctrl_c_exits_cleanly() -> None:
    lines, code, out, err = serve_then_ctrl_c(
        ["view", "--urdf", str(LITE_URDF), "--source", "sim:lite", "--port", "0"],
        "robocal view: serving http://127.0.0.1:",
    )
    assert len(lines) == 1  # the first line says where the page is
    assert (code, err, out) == (0, "", "")


def test_lerobot_sim_arm_through_its_calibration(tmp_path: Path) -> None:
    import json

    from robocal.workflows.lerobot import robot_spec

    spec = robot_spec("so101_follower")
    ranges = {
        "shoulder_pan": (900, 3300),
        "shoulder_lift": (780, 3150),
        "elbow_flex": (850, 3100),
        "wrist_flex": (0, 4095),
        "wrist_roll": (113, 3981),
        "gripper": (2000, 3400),
    }
    cal = {
        m.name: {"id": m.motor_id, "drive_mode": 0, "homing_offset": 0, "range_min": lo, "range_max": hi}
        for m in spec.motors
        for lo, hi in [ranges[m.name]]
    }
    path = tmp_path / "arm.json"
    path.write_text(json.dumps(cal))
    opts = ViewOptions(
        urdf=REPO / "src" / "robocal" / "data" / "so101_shapes.urdf",
        lerobot_port="sim",
        robot="so101_follower",
        calibration=path,
        compare="none",
        port=0,
    )
    with open_view(opts) as session:
        wait_for(lambda: session.app.updates >= 2)
        joints = {j["name"]: j for j in session.app.status()["joints"]}
    # the simulated arm rests at its mid pose: shoulder_pan at tick 2100, the middle of its range (DEGREES: 0 rad)
    assert joints["shoulder_pan"]["raw"] == 2100.0
    assert joints["shoulder_pan"]["q"] == pytest.approx(0.0, abs=1e-12)
    assert joints["shoulder_pan"]["q_compare"] == pytest.approx((2100 - 2048) * 2 * np.pi / 4096, abs=1e-12)
    # shoulder_lift: LeRobot DEGREES, (present − mid)·2π/4095 with mid = (780 + 3150)/2
    assert joints["shoulder_lift"]["q"] == pytest.approx((1950 - 1965) * 2 * np.pi / 4095, abs=1e-12)
    # the gripper (a range-mode motor): the tick angle about the middle of its range
    assert joints["gripper"]["q"] == pytest.approx((2300 - 2700) * 2 * np.pi / 4096, abs=1e-12)
    assert session.app.raw_unit == "ticks"


@pytest.mark.slow
def test_demo_view_serves_the_calibrated_lite() -> None:
    lines, code, _out, err = serve_then_ctrl_c(["demo", "--view", "--port", "0"], "robocal view: serving http://127.0.0.1:")
    assert any("largest error" in ln for ln in lines)
    assert code == 0, err
    assert err == ""


def test_demo_view_only_for_the_lite(capsys: pytest.CaptureFixture[str]) -> None:
    code, _, err = run_cli(["demo", "--robot", "so101", "--view"], capsys)
    assert code == 2 and err.startswith("error: --view shows the Lite demo")


def six_joint_urdf(tmp_path: Path) -> Path:
    joints = []
    for k in range(6):
        joints.append(
            f'<link name="l{k + 1}"/><joint name="j{k + 1}" type="revolute"><parent link="l{k}"/>'
            f'<child link="l{k + 1}"/><origin xyz="0 0 0.1"/><axis xyz="0 {k % 2} {1 - k % 2}"/>'
            '<limit lower="-6.3" upper="6.3" effort="1" velocity="1"/></joint>'
        )
    p = tmp_path / "six.urdf"
    p.write_text('<robot name="six"><link name="l0"/>' + "".join(joints) + "</robot>")
    return p


def test_ur_host_shows_the_controllers_joints(tmp_path: Path) -> None:
    from robocal.backends.sim.ur_controller import SimUrController
    from robocal.core.ur import nominal_dh

    with SimUrController(nominal_dh("ur3e"), rate_hz=50.0) as sim:
        host, port = sim.address
        opts = ViewOptions(urdf=six_joint_urdf(tmp_path), ur_host=f"{host}:{port}", port=0)
        seen: list[list[float]] = []
        with open_view(opts) as session:

            def two_poses() -> bool:
                u = session.app.last_update
                if u is not None and (not seen or seen[-1] != u.q.tolist()):
                    seen.append(u.q.tolist())
                return len(seen) >= 2

            wait_for(two_poses)
    assert all(len(q) == 6 and all(math.isfinite(x) for x in q) for q in seen)
    assert seen[0] != seen[1]  # the simulated controller moves


def test_ur_host_refuses_joint_calibrations(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    code, _, err = run_cli(
        ["view", "--urdf", str(six_joint_urdf(tmp_path)), "--ur-host", "127.0.0.1", "--compare", "none"],
        capsys,
    )
    assert code == 2 and "robocal ur view" in err


@pytest.mark.slow
def test_cli_source_that_does_not_answer(capsys: pytest.CaptureFixture[str]) -> None:
    """A CAN bus with no motor: the page serves, the failure is one error line, exit 3 (device)."""
    code, out, err = run_cli(
        [
            "view",
            "--urdf",
            str(LITE_URDF),
            "--source",
            "can:virtual:robocal-view-test-nobody",
            "--port",
            "0",
            "--duration",
            "3",
        ],
        capsys,
    )
    assert code == 3
    assert out.startswith("robocal view: serving")
    assert err.count("\n") == 1 and err.startswith(
        "error: no reply within 0.1 s from motor 'left_shoulder_pitch'"
    )
    assert err.rstrip().endswith("(the page keeps the last pose; Ctrl-C to stop)")


def test_replay_rosbag2_mcap_with_the_slider(tmp_path: Path) -> None:
    bag = tmp_path / "session"
    write_joint_states(bag, ["right_elbow_pitch"], [0.0, 0.25, 0.5], [[-0.1], [-2.5], [-0.3]])
    with open_view(ViewOptions(urdf=LITE_URDF, source=f"replay:{bag}", port=0)) as session:
        feed = session.feed
        feed.pause()  # type: ignore[attr-defined]
        feed.seek(1.25)  # type: ignore[attr-defined]  # recording time: header stamps from 1 s
        wait_for(lambda: session.app.last_update is not None and session.app.last_update.frame.t_s == 1.25)
        status = session.app.status()
    elbow = next(j for j in status["joints"] if j["name"] == "right_elbow_pitch")
    # no calibration: q = direction·raw = the recorded identity-frame value; −2.5 is below the −2.356 limit
    assert elbow["q"] == pytest.approx(-2.5) and elbow["outside"] is True and elbow["color"] == "red"
    assert status["replay"]["start_s"] == 1.0 and status["replay"]["end_s"] == 1.5


def test_missing_meshes_one_warning_line(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    rec = tmp_path / "rec.csv"
    write_csv(rec, ["shoulder_pan"], [[0.0, 0.1]])
    so101 = REPO / "src" / "robocal" / "data" / "so101_new_calib.urdf"
    code, out, err = run_cli(
        ["view", "--urdf", str(so101), "--source", f"replay:{rec}", "--port", "0", "--duration", "0.3"],
        capsys,
    )
    assert code == 0 and out.startswith("robocal view: serving")
    assert err.count("\n") == 1
    assert err.startswith(
        "warning: 17 mesh(es) of so101_new_calib.urdf could not be loaded and are drawn as simple shapes"
    )


def test_compare_file_with_a_flipped_direction_diverges_only_on_that_joint(tmp_path: Path) -> None:
    text = LITE_CAL.read_text()
    i = text.index("left_elbow_pitch:")
    flipped = tmp_path / "flipped.yaml"
    flipped.write_text(text[:i] + text[i:].replace("direction: -1", "direction: 1", 1))
    opts = ViewOptions(
        urdf=LITE_URDF, source="sim:lite?seed=5", calibration=LITE_CAL, compare=str(flipped), port=0
    )
    with open_view(opts) as session:
        wait_for(lambda: session.app.updates >= 2)
        u = session.app.last_update
    assert u is not None and u.q_compare is not None
    names = list(session.app.joint_names)
    k = names.index("left_elbow_pitch")
    assert u.q_compare[k] == pytest.approx(-u.q[k], abs=1e-12) and abs(u.q[k]) > 1e-3
    others = [i for i in range(len(names)) if i != k]
    np.testing.assert_array_equal(u.q_compare[others], u.q[others])
    assert session.app.status()["compare"] == "flipped.yaml"
