"""``robocal demo --auto --robot so101``: the simulated SO-101 follower finds its own stops through the Feetech SDK."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

from robocal.cli.main import main
from robocal.formats.lerobot import calibration_path
from robocal.workflows.lerobot import robot_spec

pytestmark = pytest.mark.timeout(900)


@pytest.mark.slow
def test_cli_demo_auto_so101(tmp_path: Path) -> None:
    r = subprocess.run(
        [sys.executable, "-m", "robocal", "demo", "--auto", "--robot", "so101", "--out", str(tmp_path)],
        capture_output=True,
        text=True,
        timeout=900,
        env={**os.environ, "COLUMNS": "200"},
    )
    assert r.returncode == 0, r.stderr[-2000:]
    out = r.stdout
    assert "automatic hard-stop calibration" in out and "true vs recovered hard stops" in out
    spec = robot_spec("so101_follower")
    for name in spec.motor_names:
        assert name in out
    assert " !" not in out  # no recovered stop outside the demo's tolerance
    path = calibration_path(spec.kind, spec.device_name, "demo", root=tmp_path)
    doc = json.loads(path.read_text())
    assert list(doc) == list(spec.motor_names)
    assert all(
        set(v) >= {"id", "drive_mode", "homing_offset", "range_min", "range_max"} for v in doc.values()
    )
    assert "s simulated; wrote" in out


def test_demo_auto_with_identify_is_refused_before_anything_runs(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "out"
    code = main(["demo", "--auto", "--identify", "--robot", "so101", "--out", str(out)])
    assert code == 2
    assert capsys.readouterr().err.strip().splitlines() == [
        "error: --auto is its own demo; it does not go with --identify"
    ]
    assert not out.exists() or list(out.iterdir()) == []
