"""``robocal sweep --view`` without a browser: the overlay's codes and arcs, the CLI wiring and its errors."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest

from robocal.cli.main import main

pytest.importorskip("viser")
pytest.importorskip("yourdfpy")

from tests.net import busy_port

from robocal.viewer.sweep_page import (
    OTHER_RGB,
    STATUS_RGB,
    arc_points,
    line_rgb,
    open_sweep_page,
    status_rgb,
)
from robocal.workflows.sweep.job import SweepRequest, run_sweep


def test_arc_points_follow_the_joint_rotation() -> None:
    pts = arc_points((0.0, 0.0, 1.0), -math.pi / 2, math.pi / 2, 0.1, n=2)
    np.testing.assert_allclose(pts, [[0.0, -0.1, 0.0], [0.1, 0.0, 0.0], [0.0, 0.1, 0.0]], atol=1e-12)
    pts = arc_points((0.0, 1.0, 0.0), 0.0, 1.0, 0.2, n=10)  # about y: stays in the x-z plane, radius 0.2
    np.testing.assert_allclose(pts[:, 1], 0.0, atol=1e-12)
    np.testing.assert_allclose(np.linalg.norm(pts, axis=1), 0.2)
    # the rotation by θ about the axis carries the start point to the point at θ
    c, s = math.cos(1.0), math.sin(1.0)
    Ry = np.array([[c, 0, s], [0, 1, 0], [-s, 0, c]])
    np.testing.assert_allclose(Ry @ pts[0], pts[-1], atol=1e-12)


def test_status_colours() -> None:
    assert status_rgb("ok") == STATUS_RGB["ok"] and status_rgb("offset_large") == OTHER_RGB
    assert tuple(line_rgb((255, 255, 255))) == (255, 255, 255) and tuple(line_rgb((0, 0, 0))) == (0, 0, 0)
    assert tuple(int(v) for v in line_rgb((245, 150, 0))) == (233, 78, 0)  # sRGB 150 is linear 78


@pytest.mark.slow
def test_overlay_takes_the_report_codes(tmp_path: Path, urdf: Path) -> None:
    prior = tmp_path / "prior.yaml"
    run_sweep(SweepRequest(urdf, "sim:lite?seed=8", prior))
    web = open_sweep_page(urdf, port=0)
    try:
        rep = tmp_path / "r.json"
        src = "sim:lite?seed=8&skip=left_elbow_pitch&short=right_elbow_pitch:1.0"
        run_sweep(SweepRequest(urdf, src, tmp_path / "cal.yaml", prior=prior, report=rep), view=web)
        report = json.loads(rep.read_text())["joints"]
        arcs = {a["name"]: a for a in web.overlay.status()["joints"]}
        for name, entry in report.items():
            code = (entry["warnings"] or ["ok"])[0]
            assert arcs[name]["status"] == code
            assert arcs[name]["color"] == list(status_rgb(code))
            assert arcs[name]["sampled_min"] == pytest.approx(entry["sampled_min"])
        assert arcs["left_elbow_pitch"]["status"] == "not_swept"
        assert arcs["right_elbow_pitch"]["status"] == "span_mismatch"
        assert web.app.source_state == "finished"
    finally:
        web.app.stop()


@pytest.mark.slow
def test_cli_view_prints_the_page_and_sweeps(
    tmp_path: Path, urdf: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "cal.yaml"
    args = ["sweep", "--urdf", str(urdf), "--source", "sim:lite?seed=8", "--out", str(out)]
    assert main([*args, "--view", "--view-port", "0"]) == 0
    err = capsys.readouterr().err
    assert "sweep view: http://127.0.0.1:" in err
    assert out.exists()


def test_cli_view_bad_input_writes_nothing(
    tmp_path: Path, urdf: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "cal.yaml"
    with busy_port() as port:
        args = ["sweep", "--urdf", str(urdf), "--source", "sim:lite?seed=8", "--out", str(out)]
        assert main([*args, "--view", "--view-port", str(port)]) == 2
    err = capsys.readouterr().err
    assert f"port {port}" in err and err.count("error:") == 1 and "Traceback" not in err
    assert not out.exists()
    bad = tmp_path / "bad.urdf"
    bad.write_text("<robot name='x'><link name='a'>")
    assert main(["sweep", "--urdf", str(bad), "--source", "sim:lite", "--out", str(out), "--view"]) == 2
    err = capsys.readouterr().err
    assert "bad.urdf" in err and err.count("error:") == 1
    assert not out.exists()
