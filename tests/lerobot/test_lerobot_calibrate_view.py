"""``robocal lerobot calibrate --view``: the recorded ranges on the arm, with the sweep report's status codes."""

from __future__ import annotations

import math
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest

from robocal.cli.main import main

pytest.importorskip("viser")
pytest.importorskip("yourdfpy")

from robocal.viewer.lerobot_sweep_page import LeRobotSweepWebView, open_lerobot_sweep_page

pytestmark = pytest.mark.timeout(120)
MOTORS = ("shoulder_pan", "shoulder_lift", "elbow_flex", "wrist_flex", "wrist_roll", "gripper")


def test_ticks_about_the_half_turn() -> None:
    np.testing.assert_allclose(
        LeRobotSweepWebView.to_rad([2048, 3072, 1024, 0]), [0.0, math.pi / 2, -math.pi / 2, -math.pi]
    )


def test_ranges_get_the_sweep_codes() -> None:
    web = open_lerobot_sweep_page("so101_follower", MOTORS, port=0)
    try:
        model = web.app.model
        assert set(MOTORS) <= set(model.actuated)
        mins, maxs = [], []
        for m in MOTORS:
            j = model.joint(m)
            lo, hi = (j.lower, j.upper)
            if m == "shoulder_pan":  # not moved
                lo = hi = 0.0
            elif m == "elbow_flex":  # moved the wrong way round: the range is mirrored beyond the upper limit
                lo, hi = hi + 0.3, hi + 0.3 + (j.upper - j.lower)
                hi = min(hi, math.pi - 0.01)
            mins.append(round(lo / (2 * math.pi) * 4096 + 2048))
            maxs.append(round(hi / (2 * math.pi) * 4096 + 2048))
        view = SimpleNamespace(
            names=MOTORS, present=tuple(maxs), minimum=tuple(mins), maximum=tuple(maxs), step=1
        )
        web(view, final=True)
        arcs = {a["name"]: a for a in web.overlay.status()["joints"]}
        assert arcs["shoulder_pan"]["status"] == "not_swept"
        assert arcs["elbow_flex"]["status"] == "no_overlap"
        assert arcs["wrist_flex"]["status"] == "ok" and arcs["shoulder_lift"]["status"] == "ok"
        assert web.result is not None and web.result["elbow_flex"].status == "no_overlap"
    finally:
        web.app.stop()


def test_cli_view_prints_the_page(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    args = ["lerobot", "calibrate", "--robot", "so101_follower", "--port", "sim", "--id", "arm1"]
    assert main([*args, "--calibration-dir", str(tmp_path), "--view", "--view-port", "0"]) == 0
    out = capsys.readouterr()
    assert "calibration view: http://127.0.0.1:" in out.err
    assert (tmp_path / "robots" / "so_follower" / "arm1.json").exists()
