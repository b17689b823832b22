"""``kinematics simulate --ticks``: the encoder resolution of the simulated joint readings (0: exact readings)."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest

from robocal.formats.kinematic_data import parse_measurements

from .conftest import JOINTS, identify_cli, simulate


@pytest.mark.slow
def test_noise_free_session_from_the_cli_recovers_the_points_below_a_micrometre(
    tmp_path: Path, capsys
) -> None:
    """Issue 13's noise-free bar as a user runs it: no marker noise, exact readings, 17 held-out poses."""
    assert simulate(tmp_path, "--noise-mm", "0", "--ticks", "0", "--validation-poses", "17") == 0
    capsys.readouterr()
    assert json.loads((tmp_path / "truth.json").read_text())["ticks_per_turn"] == 0
    held_out = str(tmp_path / "points_validation.csv")
    assert identify_cli(tmp_path, tmp_path / "points.csv", tmp_path, "--validate-data", held_out) in (0, 1)
    out = capsys.readouterr().out
    rep = json.loads((tmp_path / "report.json").read_text())
    assert rep["rank"] == 23
    assert rep["errors_mm"]["validation"]["corrected"]["max"] < 1e-3  # < 1 µm
    assert rep["errors_mm"]["validation"]["nominal"]["mean"] > 5.0
    assert "→ corrected mean 0.000 µm" in out and "the marker noise" not in out


@pytest.mark.slow
@pytest.mark.parametrize("ticks", [4096, 1024])
def test_readings_are_whole_ticks(tmp_path: Path, ticks: int) -> None:
    assert simulate(tmp_path, "--poses", "30", "--ticks", str(ticks)) == 0
    data, _ = parse_measurements((tmp_path / "points.csv").read_text(), "points", JOINTS)
    steps = data.q_rad / (2.0 * math.pi / ticks)
    np.testing.assert_allclose(steps, np.round(steps), atol=1e-9)
    assert json.loads((tmp_path / "truth.json").read_text())["ticks_per_turn"] == ticks


@pytest.mark.parametrize("kind", ["points", "tag"])
def test_a_negative_tick_count_is_refused_before_anything_is_written(
    tmp_path: Path, capsys, kind: str
) -> None:
    assert simulate(tmp_path / "new", "--kind", kind, "--ticks", "-1") == 2
    assert capsys.readouterr().err == (
        "error: --ticks must be 0 (exact readings) or a positive count per turn, got -1\n"
    )
    assert not (tmp_path / "new").exists()
