"""robocal demo --robot openarm --auto: the simulated OpenArm calibrates itself, stores its zeros, gets LeRobot's file."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from robocal.cli.main import main


def test_demo_view_draws_the_openarms_urdf() -> None:
    from robocal.formats.urdf import read_urdf
    from robocal.workflows.demo.job import demo_urdf

    urdf = demo_urdf("openarm")
    assert urdf is not None and urdf.name == "openarm_v10_right.urdf"
    assert read_urdf(urdf).joint_names[:1] == ("openarm_right_joint1",) and demo_urdf("lite") is None


@pytest.mark.slow
@pytest.mark.timeout(600)
def test_demo_openarm_auto_end_to_end(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "demo"
    assert main(["demo", "--robot", "openarm", "--auto", "--out", str(out)]) == 0
    text = capsys.readouterr().out
    assert "simulated stops and what LeRobot will read" in text and "largest zero error 0.0" in text
    doc = json.loads((out / "robots" / "openarm_follower" / "demo.json").read_text())
    assert [(m, d["range_min"], d["range_max"]) for m, d in doc.items()] == [
        ("joint_1", -80, 200), ("joint_2", -10, 190), ("joint_3", -90, 90), ("joint_4", 0, 140),
        ("joint_5", -90, 90), ("joint_6", -45, 45), ("joint_7", -90, 90), ("gripper", -60, 0),
    ]
    report = json.loads((out / "sweep_report.json").read_text())
    assert max(abs(v) for v in report["zero_stored_at_deg"].values()) <= 0.05
