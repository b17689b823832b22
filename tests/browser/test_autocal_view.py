"""``robocal sweep --auto --view`` in headless Chromium: the stop search drawn live, then the report's codes."""

from __future__ import annotations

import json
import math
import threading
import time
from pathlib import Path
from typing import Any

import browserlib
import numpy as np
import pytest

from robocal.viewer.autocal_page import open_auto_sweep_page
from robocal.viewer.sweep_page import FAIL_RGB, STATUS_RGB
from robocal.workflows.autocal.sweep import SweepAutoRequest, run_sweep_auto

pytest.importorskip("viser", reason="viser comes with robocal[view]")

LITE_URDF = Path(__file__).resolve().parents[2] / "examples" / "lite" / "lite_bimanual.urdf"
# Three joints of the simulated Lite; the left wrist roll has no upper stop (its search fails: missing_stop).
SOURCE = "sim:lite?seed=0&missing=left_wrist_roll"
JOINTS = ["left_wrist_roll", "left_elbow_pitch", "right_elbow_pitch"]



def _auto_state(page: Any) -> dict[str, Any] | None:
    return browserlib.page_state(page, "robocal-autocal", "data-autocal")


class Pace:
    """An inner view that lets wall time pass per reading: the simulated clock runs far faster than a real robot,
    and the page (polled by the test) should see a joint move. Until the test has seen that (``seen_moving``),
    each reading waits up to 50 ms for it, at most :attr:`GATE_S` in all, so a page or poller starved on a loaded
    machine still sees the joint at several positions, and the run is never held longer; then 2 ms per reading."""

    GATE_S = 20.0

    def __init__(self) -> None:
        self.seen_moving = threading.Event()
        self.gate_left_s = self.GATE_S

    def joint_start(self, name: str, cap_nm: float, speed_rad_s: float) -> None:
        pass

    def sample(self, name: str, phase: str, side: str, sample: Any) -> None:
        if self.gate_left_s > 0 and not self.seen_moving.is_set():
            t0 = time.monotonic()
            self.seen_moving.wait(min(0.05, self.gate_left_s))
            self.gate_left_s -= time.monotonic() - t0
            return
        time.sleep(0.002)

    def joint_done(self, outcome: Any) -> None:
        pass


@pytest.mark.timeout(300)  # a browser, a server and a search on a loaded 2-core machine
def test_stop_search_drawn_live_then_with_the_report_codes(page: Any, tmp_path: Path) -> None:
    pace = Pace()
    web = open_auto_sweep_page(LITE_URDF, inner=pace, port=0)
    try:
        cam = web.app.server.initial_camera  # in front of the robot (it faces +x), a little above
        cam.position = (0.8, -0.2, 0.2)
        cam.look_at = (0.0, 0.0, 0.0)
        cam.up_direction = (0.0, 0.0, 1.0)
        browserlib.open_viser(page, web.app.url)
        browserlib.wait_until(lambda: _auto_state(page), what="the auto view's page state")

        report = tmp_path / "report.json"
        done: dict[str, Any] = {}

        def run() -> None:
            try:
                done["outcome"] = run_sweep_auto(
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
            except BaseException as exc:  # pragma: no cover - reported below
                done["error"] = exc

        worker = threading.Thread(target=run)
        worker.start()
        # While it runs, the page shows which joint is searched and that joint moving on the model.
        seen: dict[str, set[float]] = {}
        try:
            while worker.is_alive():
                st = _auto_state(page)
                ps = browserlib.page_state(page)
                if st and ps and st["active"] and ps["joints"]:
                    q = {j["name"]: j["q"] for j in ps["joints"]}[st["active"]]
                    searching = {j["name"]: j["status"] for j in st["joints"]}[st["active"]]
                    if q is not None and searching == "searching":
                        seen.setdefault(st["active"], set()).add(round(q, 6))
                        if len(seen[st["active"]]) >= 3:
                            pace.seen_moving.set()
                page.wait_for_timeout(50)
        finally:
            worker.join(timeout=300)
        assert "error" not in done, done.get("error")
        outcome = done["outcome"]
        web.finish(outcome.auto, outcome.result)
        moving = [n for n, qs in seen.items() if len(qs) >= 3]
        assert moving, f"no joint seen moving while searched: {seen}"
        assert set(seen) <= set(JOINTS)

        # After the run: the codes are the report's (sweep codes for passed joints, auto codes for failed).
        doc = json.loads(report.read_text())
        codes = {}
        for name in JOINTS:
            auto = doc["auto"]["joints"][name]
            codes[name] = (
                (doc["joints"][name]["warnings"] or ["ok"])[0] if auto["code"] == "ok" else auto["code"]
            )
        assert codes["left_wrist_roll"] == "missing_stop"
        assert codes["left_elbow_pitch"] == "ok" and codes["right_elbow_pitch"] == "ok"

        def final() -> dict[str, Any] | None:
            st = _auto_state(page)
            return st if st and st["finished"] else None

        try:
            state = browserlib.wait_until(final, what="the finished auto state")
        except AssertionError as exc:  # say which side lost it: the server's state, its messages, the page's
            raise AssertionError(
                f"{exc}; server: {web.status()}; messages: {web.app.messages}; page: {_auto_state(page)}"
            ) from None
        shown = {j["name"]: j for j in state["joints"]}
        for name in JOINTS:
            assert shown[name]["status"] == codes[name]
            auto = doc["auto"]["joints"][name]
            if auto["q_stop_minus_deg"] is not None:
                assert math.degrees(shown[name]["stop_minus"]) == pytest.approx(
                    auto["q_stop_minus_deg"], abs=1e-3
                )
        assert shown["left_wrist_roll"]["color"] == list(FAIL_RGB)
        assert shown["left_elbow_pitch"]["color"] == list(STATUS_RGB["ok"])
        sweep = browserlib.wait_until(
            lambda: page.evaluate(
                "() => { const e = document.getElementById('robocal-sweep');"
                " return e ? JSON.parse(e.getAttribute('data-sweep')) : null; }"
            ),
            what="the sweep overlay state",
        )
        arcs = {j["name"]: j for j in sweep["joints"]}
        assert arcs["left_elbow_pitch"]["status"] == "ok"
        assert arcs["left_elbow_pitch"]["sampled_min"] == pytest.approx(
            doc["joints"]["left_elbow_pitch"]["sampled_min"]
        )
        msgs = browserlib.page_state(page)
        assert msgs is not None and msgs["source"] == "finished"

        # Pixels: the green arcs of the passed elbows and the crimson arc of the failed wrist are on the canvas.
        def arcs_drawn() -> np.ndarray | None:
            img = browserlib.scene_region(
                page, browserlib.screenshot(page, browserlib.shot("view_autocal.png", tmp_path))
            )
            green = browserlib.shade_mask(img, STATUS_RGB["ok"]).sum()
            crimson = browserlib.shade_mask(img, FAIL_RGB).sum()
            return img if green > 80 and crimson > 30 else None

        browserlib.wait_until(arcs_drawn, what="green and crimson arcs on the canvas")
    finally:
        web.app.stop()
