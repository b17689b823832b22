"""``sweep --auto --view`` / ``demo --auto --view``: the stop search drawn on the model (server side).

The browser side (pixels, the page's JSON) is tests/browser/test_autocal_view.py.
"""

from __future__ import annotations

import json
import math
from pathlib import Path
from types import SimpleNamespace
from typing import Any

import pytest

pytest.importorskip("viser")  # robocal[view]; installed by the [test] extra

from tests.net import busy_port

from robocal.cli.main import main
from robocal.viewer.autocal_page import open_auto_sweep_page
from robocal.viewer.sweep_page import FAIL_RGB, LIVE_RGB, STATUS_RGB, status_rgb
from robocal.workflows.autocal.sweep import SweepAutoRequest, run_sweep_auto

from .autocal_pages import Recorder, assert_page_shows_the_report
from .conftest import LITE_URDF, serve_then_ctrl_c

JOINTS = ["left_wrist_roll", "left_wrist_pitch", "right_elbow_pitch"]
SOURCE = "sim:lite?seed=0&missing=left_wrist_roll"


def test_status_colours_of_the_auto_codes() -> None:
    assert status_rgb("searching") == LIVE_RGB["searching"]
    assert status_rgb("missing_stop") == FAIL_RGB and status_rgb("blocked") == FAIL_RGB
    assert status_rgb("span_mismatch") == STATUS_RGB["span_mismatch"]  # the report's colour wins
    assert status_rgb("wrap_in_travel") == STATUS_RGB["wrap_in_travel"]
    assert status_rgb("offset_large") not in (FAIL_RGB, *STATUS_RGB.values())
    assert status_rgb("not_searched") == STATUS_RGB["not_swept"] == (150, 150, 150)  # grey, not a warning


def test_lerobot_auto_page_draws_not_searched_joints_grey() -> None:
    """The Koch's full-turn joints (``stops: none``) are never moved: grey on the page, in the legend too."""
    from robocal.viewer.lerobot_sweep_page import open_lerobot_auto_page
    from robocal.workflows.lerobot import robot_spec

    spec = robot_spec("koch_follower")
    web = open_lerobot_auto_page("koch_follower", spec.motor_names, port=0)
    try:
        stops = SimpleNamespace(
            code="not_searched", reason="full turn: no hard stop", lower=None, upper=None, span_rad=math.nan
        )
        web.joint_done(SimpleNamespace(name="shoulder_pan", ok=True, stops=stops))
        web.finish(SimpleAuto([SimpleNamespace(name="shoulder_pan", ok=True, stops=stops)]))
        joints = web.status()["joints"]
        entry = next(j for j in joints if j["status"] == "not_searched")
        assert entry["color"] == [150, 150, 150]
        assert entry["stop_minus"] is None and entry["stop_plus"] is None  # nothing found, nothing drawn
    finally:
        web.app.stop()


@pytest.mark.slow
def test_the_search_drawn_with_the_report_codes(tmp_path: Path) -> None:
    rec = Recorder()
    web = open_auto_sweep_page(LITE_URDF, inner=rec, port=0)
    try:
        report = tmp_path / "report.json"
        outcome = run_sweep_auto(
            SweepAutoRequest(
                LITE_URDF,
                SOURCE,
                tmp_path / "cal.yaml",
                joints=JOINTS,
                report=report,
                partial=True,
            ),
            view=web,
        )
        web.finish(outcome.auto, outcome.result)
        # every call reached the terminal's view too, in the search order
        assert [c for c in rec.calls if c[0] == "start"] == [("start", o.name) for o in outcome.auto.joints]
        state = assert_page_shows_the_report(web, json.loads(report.read_text()), rec, JOINTS)
        assert web.status()["active"] is None
        for name in JOINTS:  # the joint drawn where it last read
            assert state[name]["current"] == pytest.approx(rec.q[name][-1])
        assert state["left_wrist_roll"]["status"] == "missing_stop"
        assert state["left_wrist_roll"]["color"] == list(FAIL_RGB)
        # a joint not searched has no arc
        assert (
            state["left_shoulder_pitch"]["status"] == "waiting"
            and state["left_shoulder_pitch"]["color"] is None
        )

        # the overlay's arcs: the found stops of a passed joint, the travelled range of the failed one
        arcs = {a.name: a for a in web.overlay.arcs()}
        passed = outcome.auto["left_wrist_pitch"].stops
        assert passed.ok and passed.lower is not None and passed.upper is not None
        assert arcs["left_wrist_pitch"].sampled_min == pytest.approx(passed.lower.q_stop_rad)
        assert arcs["left_wrist_pitch"].sampled_max == pytest.approx(passed.upper.q_stop_rad)
        assert arcs["left_wrist_roll"].sampled_min == pytest.approx(min(rec.q["left_wrist_roll"]))
        assert arcs["left_wrist_roll"].status == "missing_stop"

        # the robot is posed by the readings: after a page update every searched joint is at its last reading
        web.app.step()
        u = web.app.last_update
        assert u is not None
        for name in JOINTS:
            assert u.q[web.app.joint_names.index(name)] == pytest.approx(rec.q[name][-1])
        assert web.app.slot.frames_in >= sum(len(v) for v in rec.q.values())
        # the found-stop ticks: two for a joint with both stops, one for the missing upper stop
        web.app.step()
        assert web._ticks["left_wrist_pitch"].points.shape == (2, 2, 3)
        assert web._ticks["left_wrist_roll"].points.shape == (1, 2, 3)
        assert web._ticks["left_shoulder_pitch"].visible is False
    finally:
        web.app.stop()


def run_cli(args: list[str], capsys: pytest.CaptureFixture[str]) -> tuple[int, str, str]:
    code = main(args)
    out, err = capsys.readouterr()
    return code, out, err


@pytest.mark.slow
def test_cli_sweep_auto_view(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "cal.yaml"
    args = ["sweep", "--auto", "--urdf", str(LITE_URDF), "--source", "sim:lite?seed=0", "--out", str(out)]
    code, stdout, err = run_cli(
        [*args, "--joints", "right_elbow_pitch,right_wrist_pitch", "--yes", "--view", "--view-port", "0"],
        capsys,
    )
    assert code == 0, err
    assert err.startswith("auto-calibration view: http://127.0.0.1:")
    assert "right_wrist_pitch: ok" in err and f"wrote {out}" in stdout
    assert out.is_file()


def test_cli_sweep_auto_view_port_in_use_moves_nothing(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "cal.yaml"
    with busy_port() as port:
        code, _, err = run_cli(
            [
                "sweep",
                "--auto",
                "--urdf",
                str(LITE_URDF),
                "--source",
                "sim:lite?seed=0",
                "--out",
                str(out),
                "--yes",
                "--view",
                "--view-port",
                str(port),
            ],
            capsys,
        )
    assert code == 2
    lines = err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith(f"error: port {port} on 127.0.0.1 is in use")
    assert not out.exists() and list(tmp_path.iterdir()) == []


@pytest.mark.slow
def test_cli_sweep_auto_view_failed_joint_shown_exit_3(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "cal.yaml"
    code, _, err = run_cli(
        [
            "sweep",
            "--auto",
            "--urdf",
            str(LITE_URDF),
            "--source",
            SOURCE,
            "--out",
            str(out),
            "--joints",
            "left_wrist_roll",
            "--yes",
            "--view",
            "--view-port",
            "0",
        ],
        capsys,
    )
    assert code == 3
    assert (
        err.strip()
        .splitlines()[-1]
        .startswith("error: auto-calibration failed for left_wrist_roll: missing_stop")
    )
    assert not out.exists()


@pytest.mark.slow
def test_demo_auto_view_serves_the_result_until_ctrl_c() -> None:
    lines, code, _out, err = serve_then_ctrl_c(
        ["demo", "--auto", "--view", "--port", "0"], "serving the result at http://127.0.0.1:"
    )
    assert any("largest error" in ln for ln in lines)
    assert code == 0, err
    assert err.startswith("auto-calibration view: http://127.0.0.1:")
    assert "Traceback" not in err


def _outcome(name: str, lo_rad: float, hi_rad: float) -> Any:
    """A passed joint's outcome as the auto run hands it to its view (name, ok, stops with both surfaces)."""

    stops = SimpleNamespace(
        name=name,
        code="ok",
        reason="",
        lower=SimpleNamespace(q_stop_rad=lo_rad),
        upper=SimpleNamespace(q_stop_rad=hi_rad),
        span_rad=hi_rad - lo_rad,
    )
    return SimpleNamespace(name=name, ok=True, stops=stops)


@pytest.mark.parametrize(
    ("robot", "motor", "joint"),
    [("so101_follower", "elbow_flex", "elbow_flex"), ("koch_follower", "shoulder_lift", "joint2")],
)
def test_lerobot_auto_page_draws_servo_angles_about_the_middle_pose(
    robot: str, motor: str, joint: str
) -> None:
    """The servo drivers count ``ticks·2π/4096`` from 0; the arm's URDF has its zero at 2048 ticks."""
    from robocal.core.stop_search import StopSample
    from robocal.viewer.lerobot_sweep_page import open_lerobot_auto_page
    from robocal.workflows.lerobot import robot_spec

    spec = robot_spec(robot)
    web = open_lerobot_auto_page(robot, spec.motor_names, port=0)
    try:
        tick = 2.0 * math.pi / 4096
        web.joint_start(motor, 0.5, 0.3)
        for k, ticks in enumerate((2048, 1500, 1024, 2600, 3072)):
            web.sample(motor, "approach", "lower", StopSample(0.01 * k, ticks * tick, 0.0, 0.1))
        assert web.status()["active"] == joint
        web.joint_done(_outcome(motor, 1000 * tick, 3100 * tick))
        web.finish(SimpleAuto([_outcome(motor, 1000 * tick, 3100 * tick)]))
        entry = {j["name"]: j for j in web.status()["joints"]}[joint]
        assert entry["status"] == "ok"
        assert entry["seen_min"] == pytest.approx((1024 - 2048) * tick)
        assert entry["seen_max"] == pytest.approx((3072 - 2048) * tick)
        assert entry["stop_minus"] == pytest.approx((1000 - 2048) * tick)
        assert entry["stop_plus"] == pytest.approx((3100 - 2048) * tick)
        web.app.step()
        u = web.app.last_update
        assert u is not None
        assert u.q[web.app.joint_names.index(joint)] == pytest.approx((3072 - 2048) * tick)
        arcs = {a.name: a for a in web.overlay.arcs()}
        assert arcs[joint].sampled_min == pytest.approx((1000 - 2048) * tick)
    finally:
        web.app.stop()


class SimpleAuto:
    """The run's result as :meth:`AutoSweepWebView.finish` reads it (its joints' outcomes)."""

    def __init__(self, joints: list[Any]) -> None:
        self.joints = tuple(joints)


@pytest.mark.slow
def test_cli_lerobot_calibrate_auto_view(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """The simulated SO-101 through the real Feetech SDK, drawn on the arm's page; then the same with the page's
    port in use: one error line before the port opens, nothing written."""
    # the in-process port: the pty's packets (test_lerobot_auto_inproc), no polling
    args = [
        "lerobot",
        "calibrate",
        "--auto",
        "--robot",
        "so101_follower",
        "--port",
        "sim?transport=inproc",
        "--id",
        "a",
    ]
    code, stdout, err = run_cli(
        [*args, "--calibration-dir", str(tmp_path / "ok"), "--yes", "--view", "--view-port", "0"], capsys
    )
    assert code == 0, err
    assert err.startswith("auto-calibration view: http://127.0.0.1:")
    assert "calibration saved to" in stdout
    with busy_port() as port:
        code, _, err = run_cli(
            [*args, "--calibration-dir", str(tmp_path / "busy"), "--yes", "--view", "--view-port", str(port)],
            capsys,
        )
    assert code == 2
    lines = err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith(f"error: port {port} on 127.0.0.1 is in use")
    assert not list((tmp_path / "busy").rglob("*.json"))
