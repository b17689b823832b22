"""``--view`` for the OpenArm: ``sweep --auto --view`` (and ``demo --robot openarm --auto --view``) draws the stop
search on robocal's OpenArm URDF as for the Lite, with the report's codes; the live hand sweep's page is in
tests/sim/test_sim_openarm_hand_sweep.py."""

from __future__ import annotations

import json
from importlib import resources
from pathlib import Path

import pytest

pytest.importorskip("viser")  # robocal[view]
pytest.importorskip("can")

from robocal.viewer.autocal_page import open_auto_sweep_page
from robocal.viewer.sweep_page import FAIL_RGB
from robocal.workflows.autocal.damiao import sim_openarm_opener
from robocal.workflows.autocal.sweep import SweepAutoRequest, run_sweep_auto

from .autocal_pages import Recorder, assert_page_shows_the_report
from .conftest import serve_then_ctrl_c

URDF = Path(str(resources.files("robocal").joinpath("data", "openarm_v10_right.urdf")))
JOINTS = ["openarm_right_joint5", "openarm_right_joint6", "openarm_right_gripper_motor"]


def test_the_openarm_urdf_loads_on_the_page_every_joint_waiting() -> None:
    web = open_auto_sweep_page(URDF, inner=Recorder(), port=0)
    try:
        status = web.status()
        names = [f"openarm_right_joint{i}" for i in range(1, 8)] + ["openarm_right_gripper_motor"]
        assert [j["name"] for j in status["joints"]] == names
        assert all(j["status"] == "waiting" and j["color"] is None for j in status["joints"])
        assert set(names) <= set(web.app.joint_names)
    finally:
        web.app.stop()


@pytest.mark.slow
def test_the_openarm_search_drawn_with_the_report_codes(tmp_path: Path) -> None:
    rec = Recorder()
    web = open_auto_sweep_page(URDF, inner=rec, port=0)
    try:
        report = tmp_path / "report.json"
        outcome = run_sweep_auto(
            SweepAutoRequest(URDF, "sim:openarm?seed=2&missing=openarm_right_joint6", tmp_path / "cal.yaml",
                             robot="openarm_follower_right", joints=JOINTS, report=report, fmt="lite-yaml",
                             partial=True),
            view=web,
            open_drivers_fn=sim_openarm_opener(),
        )
        web.finish(outcome.auto, outcome.result)
        state = assert_page_shows_the_report(web, json.loads(report.read_text()), rec, JOINTS)
        assert state["openarm_right_joint6"]["status"] == "missing_stop"
        assert state["openarm_right_joint6"]["color"] == list(FAIL_RGB)
        assert state["openarm_right_joint5"]["status"] in ("ok", "wrap_in_travel")
        assert state["openarm_right_joint1"]["status"] == "waiting"  # not searched: no arc
        # the arm is posed by the readings: every searched joint at its last reading
        web.app.step()
        u = web.app.last_update
        assert u is not None
        for name in JOINTS:
            assert u.q[web.app.joint_names.index(name)] == pytest.approx(rec.q[name][-1])
    finally:
        web.app.stop()


@pytest.mark.slow
@pytest.mark.timeout(600)
def test_demo_openarm_auto_view_serves_the_result_until_ctrl_c(tmp_path: Path) -> None:
    lines, code, _out, err = serve_then_ctrl_c(
        ["demo", "--robot", "openarm", "--auto", "--view", "--port", "0", "--out", str(tmp_path / "d")],
        "serving the result at http://127.0.0.1:",
    )
    assert any("largest zero error" in ln for ln in lines), lines
    assert code == 0, err
    assert err.startswith("auto-calibration view: http://127.0.0.1:") and "Traceback" not in err
    assert (tmp_path / "d" / "robots" / "openarm_follower" / "demo.json").is_file()
