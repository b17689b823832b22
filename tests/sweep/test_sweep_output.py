"""What a person and a log read: full-width tables when piped, warning sentences with numbers, exit codes."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from rich.console import Console

from robocal.cli._sweep_view import LiveView
from robocal.cli.main import main
from robocal.core.sweep import analyse_sweep
from robocal.core.sweep_result import WARNING_CODES, JointSweep, SweepResult, explain_warning
from robocal.workflows.demo.job import LITE_DEMO_SOURCE, run_demo

ELBOW = "left_elbow_pitch"  # dir -1, limits [-2.356, 0]


def _robocal(*args: str, cwd: Path) -> subprocess.CompletedProcess[str]:
    """Run the CLI in a child process with stdout and stderr piped (no terminal), 80 columns as in CI."""
    env = {k: v for k, v in os.environ.items() if k not in ("COLUMNS", "LINES", "FORCE_COLOR", "TERM")}
    env["COLUMNS"] = "80"
    code = "import sys; from robocal.cli.main import main; sys.exit(main(sys.argv[1:]))"
    return subprocess.run(
        [sys.executable, "-c", code, *args], capture_output=True, text=True, cwd=cwd, env=env, timeout=120
    )


@pytest.mark.slow
def test_piped_tables_keep_full_names(urdf: Path, tmp_path: Path, h: Any) -> None:
    out = tmp_path / "cal.yaml"
    p = _robocal("sweep", "--urdf", str(urdf), "--source", "sim:lite?seed=7", "--out", str(out), cwd=tmp_path)
    assert p.returncode == 1, p.stderr  # seed 7: left_shoulder_pitch has wrap_in_travel
    assert "…" not in p.stdout
    header = next(line for line in p.stdout.splitlines() if "homing_offset" in line and "joint" in line)
    for col in ("joint", "min", "max", "sweep", "span", "homing_offset", "previous", "status"):
        assert col in header
    for name in h.names:
        assert f" {name} " in p.stdout
    assert "wrap_in_travel" in p.stdout
    assert max(len(line) for line in p.stdout.splitlines()) > 80  # wider than rich's default, not cut
    demo = _robocal("demo", "--out", str(tmp_path / "demo"), cwd=tmp_path)
    assert demo.returncode == 0, demo.stderr
    assert "…" not in demo.stdout
    assert all(f" {name} " in demo.stdout for name in h.names)


def _joint(**kw: Any) -> JointSweep:
    base: dict[str, Any] = {
        "name": ELBOW,
        "direction": -1,
        "lower": -2.356,
        "upper": 0.0,
        "sampled_min": -3.056,
        "sampled_max": -1.0,
        "sweep": 2.056,
        "homing_offset": 0.85,
        "bisection_offset": 0.85,
        "previous_homing_offset": 0.73,
        "kept_prior": False,
        "warnings": ("span_mismatch",),
    }
    base.update(kw)
    return JointSweep(**base)


def test_every_code_has_a_sentence_with_its_numbers() -> None:
    s = explain_warning(_joint(), "span_mismatch", 0.5, 0.15)
    assert s.startswith("swept 2.056 rad but the URDF span is 2.356 rad (-0.300 rad, tolerance 0.15 rad)")
    assert "push it fully into both stops" in s
    s = explain_warning(_joint(sweep=0.3, kept_prior=True, homing_offset=0.73), "not_swept", 0.5, 0.15)
    assert s.startswith("swept only 0.300 rad (threshold 0.5 rad), so the prior offset +0.7300 rad was kept")
    s = explain_warning(_joint(sampled_min=0.5, sampled_max=2.856), "no_overlap")
    assert "[+0.500, +2.856] rad does not overlap the URDF limits [-2.356, +0.000] rad" in s
    assert "--direction-check" in s
    assert "homing_offset +3.644 rad is beyond ±π" in explain_warning(
        _joint(homing_offset=3.644), "offset_large"
    )
    # elbow, direction -1, offset -0.5: raw travel [-0.5, 1.856] contains the zero_sta 0 wrap point 0
    s = explain_warning(_joint(homing_offset=-0.5), "wrap_in_travel")
    assert "raw travel [-0.500, +1.856] rad contains the power-on wrap point +0.000 rad" in s
    s = explain_warning(_joint(homing_offset=2.5, zero_sta=1), "wrap_in_travel")
    assert "raw travel [+2.500, +4.856] rad contains the power-on wrap point +3.142 rad" in s
    assert "flip its URDF direction (now -1)" in explain_warning(_joint(), "direction_flipped")
    assert "NOT verified" in explain_warning(_joint(), "direction_unknown")
    for code in WARNING_CODES:
        assert explain_warning(_joint(), code) != code  # every code is explained


def test_sweep_prints_the_sentence_with_the_measured_numbers(
    urdf: Path, tmp_path: Path, h: Any, capsys: pytest.CaptureFixture[str]
) -> None:
    from tests.sweep.test_sweep_cli import csv_sweep, elbow

    rec = tmp_path / "sweep.csv"
    csv_sweep(rec, h.names, h.dirs, {ELBOW: elbow(-3.056, -1.0)})
    rep = tmp_path / "r.json"
    args = ["sweep", "--urdf", str(urdf), "--source", f"replay:{rec}", "--out", str(tmp_path / "c.yaml")]
    assert main([*args, "--report", str(rep)]) == 1
    err = capsys.readouterr().err
    entry = json.loads(rep.read_text())["joints"][ELBOW]
    line = next(x for x in err.splitlines() if x.startswith(f"warning: {ELBOW}: span_mismatch: "))
    assert (
        f"swept {entry['sweep']:.3f} rad but the URDF span is 2.356 rad (-0.300 rad, tolerance 0.15 rad)"
        in line
    )
    assert line.count("\n") == 0 and "push it fully into both stops" in line


def test_live_view_explains_a_warning_as_soon_as_it_shows(urdf: Path, tmp_path: Path, h: Any) -> None:
    from robocal.backends.sim.lite import LITE_JOINTS
    from robocal.backends.sources import JointSpec, ReplaySource
    from robocal.workflows.sweep.session import SweepSession

    joints = [JointSpec(j.name, j.can_id, j.model, j.direction, j.lower, j.upper) for j in LITE_JOINTS]
    n = len(joints)
    pos = np.zeros((2, n))
    k = h.names.index(ELBOW)
    pos[:, k] = [0.5, 2.856]  # identity frame: entirely above the elbow's URDF range [-2.356, 0]
    w = h.names.index("left_wrist_yaw")  # [-1.571, 1.571], offset +0.5 with zero_sta 0: wrap_in_travel at
    pos[:, w] = [-1.071, 2.071]  # the end, but the live view does not guess it from a moving estimate
    session = SweepSession(ReplaySource(h.names, np.array([0.0, 0.01]), pos, "identity"), joints)
    session.step()
    con = Console(record=True, width=200, force_terminal=True)
    view = LiveView(con)
    notes = view.live_notes(session)
    assert notes == [f"{ELBOW}: no_overlap: " + explain_warning(session.result()[ELBOW], "no_overlap")]
    con.print(view.table(session))
    text = con.export_text()
    assert "no_overlap: sampled range [+0.500, +2.856] rad does not overlap" in text


@pytest.mark.slow
def test_demo_and_sweep_agree_on_the_exit_code(urdf: Path, tmp_path: Path) -> None:
    # seed 7: one joint has wrap_in_travel (exit 1 for both); the default demo seed is clean (0 for both)
    for source, code in (("sim:lite?seed=7", 1), (LITE_DEMO_SOURCE, 0)):
        d = tmp_path / source.replace("?", "_").replace(":", "_").replace("=", "_")
        d.mkdir()
        assert run_demo("lite", d, source=source).exit_code == code
        assert main(["sweep", "--urdf", str(urdf), "--source", source, "--out", str(d / "c.yaml")]) == code
    assert main(["demo", "--out", str(tmp_path / "default")]) == 0


def test_result_explain_uses_the_result_tolerances() -> None:
    res: SweepResult = analyse_sweep([ELBOW], -1, -2.356, 0.0, -3.056, -1.0, span_tolerance_rad=0.2)
    assert res.explain(ELBOW, "span_mismatch").startswith("swept 2.056 rad but the URDF span is 2.356 rad")
    assert "tolerance 0.2 rad" in res.explain(ELBOW, "span_mismatch")


def test_the_output_checks_and_default_format_shared_by_sweep_and_sweep_auto(tmp_path: Path) -> None:
    from robocal.errors import UsageError
    from robocal.formats.profiles import load_profile
    from robocal.workflows.sweep.output import check_outputs, output_format

    out = tmp_path / "cal.yaml"
    assert check_outputs(str(out), None, None) == (out, None)
    assert check_outputs(out, tmp_path / "r.json", "lite-json") == (out, tmp_path / "r.json")
    with pytest.raises(UsageError, match=r"^--format 'yaml': expected one of lite-yaml, lite-json, berkeley-offsets, openarm-lerobot, openarm-ros2$"):
        check_outputs(out, None, "yaml")
    with pytest.raises(UsageError, match=r"--report .*cal\.yaml: is the same file as --out$"):
        check_outputs(out, tmp_path / "." / "cal.yaml", None)
    assert not out.exists()  # a probe, nothing left behind
    biped = load_profile("bhl_biped")
    assert output_format(Path("c.JSON"), biped) == "lite-json"  # the suffix first
    assert output_format(Path("c.yaml"), biped) == "berkeley-offsets"  # then the profile's format
    assert output_format(Path("c.yaml"), None) == "lite-yaml"
