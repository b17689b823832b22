"""A robot profile cannot raise a motor's rating: ``rated_nm: 40`` or ``1e9`` on an RS05 joint is refused (issue 26).

Before, ``rated_nm: 40`` on an RS05 joint gave ``cap 10.00 N·m`` (the default 0.40 N·m), 5.5 N·m at the stop and
exit 0, and ``rated_nm: 1e9`` was accepted.
"""

from __future__ import annotations

import subprocess
import sys
from importlib import resources
from pathlib import Path

import pytest

from robocal.backends.sim.lite import lite_urdf_text

ROW = "    - {name: left_wrist_roll, stops: both}"


def _profile(tmp_path: Path, extra: str) -> Path:
    text = (resources.files("robocal.data.profiles") / "bhl_arms.yaml").read_text(encoding="utf-8")
    assert text.count(ROW) == 1
    path = tmp_path / "arms.yaml"
    path.write_text(text.replace(ROW, ROW[:-1] + f", {extra}}}"), encoding="utf-8")
    return path


@pytest.mark.parametrize(
    ("extra", "shown"),
    [("rated_nm: 40", "rated_nm 40 N·m"), ("rated_nm: 1e9", "rated_nm 1e+09 N·m")],
)
def test_sweep_auto_refuses_a_profile_that_raises_a_motors_rating(tmp_path: Path, extra: str, shown: str) -> None:
    profile = _profile(tmp_path, extra)
    urdf = tmp_path / "lite.urdf"
    urdf.write_text(lite_urdf_text())
    before = sorted(p.name for p in tmp_path.iterdir())
    proc = subprocess.run(
        [sys.executable, "-m", "robocal", "sweep", "--auto", "--urdf", str(urdf), "--robot", str(profile),
         "--source", "sim:lite", "--out", str(tmp_path / "c.yaml"), "--yes"],
        capture_output=True, text=True, timeout=120,
    )
    assert proc.returncode == 2
    assert "Traceback" not in proc.stderr
    lines = [ln for ln in (proc.stdout + proc.stderr).splitlines() if ln.strip()]
    errors = [ln for ln in lines if ln.startswith("error:")]
    assert len(errors) == 1, lines
    assert errors[0].startswith(f"error: profile {profile}: auto_calibration: joint 'left_wrist_roll': {shown} is "
                                "above the RS05's rated torque 1.6 N·m")
    assert "never raise it" in errors[0]
    assert "cap " not in proc.stdout + proc.stderr  # refused when read: nothing was asked, nothing moved
    assert sorted(p.name for p in tmp_path.iterdir()) == before
