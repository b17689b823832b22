"""``robocal sweep --view`` in headless Chromium: the arcs carry the report's status codes and colours."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import browserlib
import numpy as np
import pytest

from robocal.viewer.sweep_page import STATUS_RGB, open_sweep_page
from robocal.workflows.sweep.job import SweepRequest, run_sweep

pytest.importorskip("viser", reason="viser comes with robocal[view]")

LITE_URDF = Path(__file__).resolve().parents[2] / "examples" / "lite" / "lite_bimanual.urdf"
# The demo's clean robot, with the left elbow never moved and the right elbow stopped 1 rad short of a stop.
SOURCE = "sim:lite?seed=8&skip=left_elbow_pitch&short=right_elbow_pitch:1.0"



def _sweep_state(page: Any) -> dict[str, Any] | None:
    return browserlib.page_state(page, "robocal-sweep", "data-sweep")


def test_sweep_arcs_have_the_report_codes(page: Any, tmp_path: Path) -> None:
    web = open_sweep_page(LITE_URDF, port=0)
    try:
        cam = web.app.server.initial_camera  # in front of the robot (it faces +x), a little above
        cam.position = (0.8, -0.2, 0.2)
        cam.look_at = (0.0, 0.0, 0.0)
        cam.up_direction = (0.0, 0.0, 1.0)
        report = tmp_path / "report.json"
        prior = tmp_path / "previous.yaml"  # an earlier clean sweep: the un-swept elbow keeps its offset
        run_sweep(SweepRequest(LITE_URDF, "sim:lite?seed=8", prior))
        outcome = run_sweep(
            SweepRequest(
                LITE_URDF,
                SOURCE,
                tmp_path / "cal.yaml",
                prior=prior,
                report=report,
            ),
            view=web,
        )
        assert web.result is outcome.result
        codes = {
            name: (entry["warnings"] or ["ok"])[0]
            for name, entry in json.loads(report.read_text())["joints"].items()
        }
        assert codes["left_elbow_pitch"] == "not_swept" and codes["right_elbow_pitch"] == "span_mismatch"
        assert sum(c == "ok" for c in codes.values()) == 12

        browserlib.open_viser(page, web.app.url)
        state = browserlib.wait_until(lambda: _sweep_state(page), what="the sweep overlay state")
        shown = {j["name"]: j for j in state["joints"]}
        assert {n: j["status"] for n, j in shown.items()} == codes  # the same codes as the report
        for name, entry in json.loads(report.read_text())["joints"].items():
            assert shown[name]["color"] == list(STATUS_RGB[codes[name]])
            assert shown[name]["sampled_min"] == pytest.approx(entry["sampled_min"])
            assert shown[name]["sampled_max"] == pytest.approx(entry["sampled_max"])
        msgs = browserlib.page_state(page)
        assert msgs is not None and msgs["source"] == "finished"
        assert any("right_elbow_pitch: span_mismatch" in m["text"] for m in msgs["messages"])

        # Pixels: green arcs (ok) and the orange arc (span_mismatch) are on the canvas.
        def arcs_drawn() -> np.ndarray | None:
            img = browserlib.scene_region(
                page, browserlib.screenshot(page, browserlib.shot("view_sweep.png", tmp_path))
            )
            green = browserlib.shade_mask(img, STATUS_RGB["ok"]).sum()
            orange = browserlib.shade_mask(img, STATUS_RGB["span_mismatch"]).sum()
            return img if green > 300 and orange > 30 else None

        browserlib.wait_until(arcs_drawn, what="green and orange arcs on the canvas")
    finally:
        web.app.stop()


@pytest.mark.slow
def test_arcs_change_colour_while_the_page_is_open(page: Any) -> None:
    """The arcs drawn after the page connected (the usual case: the page is open during the sweep) have their
    colour: a line node created with one colour was drawn white after its per-vertex colour update."""
    web = open_sweep_page(LITE_URDF, port=0)
    try:
        app = web.app
        cam = app.server.initial_camera
        cam.position = (0.8, -0.2, 0.2)
        cam.look_at = (0.0, 0.0, 0.0)
        cam.up_direction = (0.0, 0.0, 1.0)
        browserlib.open_viser(page, app.url)
        names = list(app.joint_names)
        img = browserlib.scene_region(page, browserlib.screenshot(page))
        assert browserlib.shade_mask(img, STATUS_RGB["ok"]).sum() == 0  # nothing swept yet
        web.overlay.set_ranges(
            dict.fromkeys(names, -1.0),
            dict.fromkeys(names, 0.0),
            dict.fromkeys(names, -0.5),
            dict.fromkeys(names, "ok"),
        )
        app.push(0.0, np.full(len(names), -0.5))

        def green() -> int:
            browserlib.next_frames(page)
            shot = browserlib.scene_region(page, browserlib.screenshot(page))
            n = int(browserlib.shade_mask(shot, STATUS_RGB["ok"]).sum())
            return n if n > 1000 else 0

        browserlib.wait_until(green, what="green arcs drawn while the page is open")
    finally:
        web.app.stop()
