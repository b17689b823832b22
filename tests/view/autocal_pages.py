"""Shared pieces of the auto-calibration page tests (the Lite's and the OpenArm's): the terminal view behind the
page, and the page's joint state checked against the run's JSON report."""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np
import pytest

from robocal.viewer.sweep_page import status_rgb


class Recorder:
    """An inner auto view: what the page view forwards."""

    def __init__(self) -> None:
        self.calls: list[tuple[str, str]] = []
        self.q: dict[str, list[float]] = {}

    def joint_start(self, name: str, cap_nm: float, speed_rad_s: float) -> None:
        self.calls.append(("start", name))

    def sample(self, name: str, phase: str, side: str, sample: Any) -> None:
        if sample.ok:
            self.q.setdefault(name, []).append(sample.q_rad)

    def joint_done(self, outcome: Any) -> None:
        self.calls.append(("done", outcome.name))


def assert_page_shows_the_report(
    web: Any, report: Mapping[str, Any], rec: Recorder, joints: Sequence[str]
) -> dict[str, dict[str, Any]]:
    """Each searched joint on the finished page as the report has it; returns the page's joints by name.

    A passed joint has the sweep report's code, a failed one the auto report's; its colour is that code's; its
    found stops are the report's; its travelled range is what the joint read (``rec``).
    """
    state = {j["name"]: j for j in web.status()["joints"]}
    assert web.status()["finished"] is True
    for name in joints:
        entry, auto = state[name], report["auto"]["joints"][name]
        code = (report["joints"][name]["warnings"] or ["ok"])[0] if auto["code"] == "ok" else auto["code"]
        assert entry["status"] == code and entry["color"] == list(status_rgb(code)), name
        for key, rep in (("stop_minus", "q_stop_minus_deg"), ("stop_plus", "q_stop_plus_deg")):
            if auto[rep] is None:
                assert entry[key] is None
            else:
                assert math.degrees(entry[key]) == pytest.approx(auto[rep], abs=1e-3)
        q = np.array(rec.q[name])
        assert entry["seen_min"] == pytest.approx(q.min()) and entry["seen_max"] == pytest.approx(q.max())
    return state
