"""Issue 15 (Lite): the upstream one-sided procedure, bit for bit, with its diagnostics and the live view."""

from __future__ import annotations

import csv
import io
import json
import math
from pathlib import Path

import numpy as np
import pytest
from lite_testutil import (
    BIMANUAL_URDF,
    BIPED_URDF,
    REPLAY,
    UPSTREAM_CAL,
    UPSTREAM_DIRS,
    UPSTREAM_IDEAL_DEG,
    UPSTREAM_SIDE,
    URDF_ORDER,
)
from rich.console import Console
from ruamel.yaml import YAML

from robocal.backends.sources import open_source
from robocal.cli._sweep_view import LiveView
from robocal.cli.main import main
from robocal.core.sweep import analyse_sweep, one_sided_position_offset
from robocal.formats import read_calibration
from robocal.formats.urdf import read_urdf
from robocal.workflows.sweep.job import SweepRequest, run_sweep
from robocal.workflows.sweep.joint_specs import joints_from_urdf
from robocal.workflows.sweep.session import SweepSession


def _replay(path: Path = REPLAY) -> tuple[list[str], np.ndarray]:
    with open(path, newline="") as f:
        rows = list(csv.reader(f))
    return rows[0][1:], np.array([[float(v) for v in r[1:]] for r in rows[1:]])


def upstream_formula(samples: np.ndarray) -> list[float]:
    """Upstream's calibrate_joints.py, restated: running min/max of direction*raw, minus the ideal angle."""
    limit = samples[0].copy()
    for row in samples:
        for i, side in enumerate(UPSTREAM_SIDE):
            limit[i] = min(limit[i], row[i]) if side == "min" else max(limit[i], row[i])
    return [float(limit[i] - np.deg2rad(UPSTREAM_IDEAL_DEG[i])) for i in range(12)]


def _offsets(path: Path) -> list[float]:
    return [float(v) for v in YAML(typ="safe").load(path.read_text())["position_offsets"]]


def _sweep(
    tmp_path: Path, replay: Path, *extra: str, out: str = "calibration.yaml"
) -> tuple[int, Path, Path]:
    o, r = tmp_path / out, tmp_path / "report.json"
    rc = main(["sweep", "--urdf", str(BIPED_URDF), "--source", f"replay:{replay}", "--out", str(o),
               "--report", str(r), *extra])  # fmt: skip
    return rc, o, r


def test_one_sided_sweep_equals_upstream_formula(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    names, s = _replay()
    assert names == URDF_ORDER
    expected = upstream_formula(s)
    rc, out, report = _sweep(tmp_path, REPLAY, "--robot", "bhl_biped", "--method", "one-sided")
    assert rc == 0, capsys.readouterr().err
    got = _offsets(out)
    assert np.max(np.abs(np.subtract(got, expected))) <= 1e-9
    assert got == expected  # in fact bit for bit
    assert got == _offsets(UPSTREAM_CAL)  # the file upstream's own procedure wrote for this recording
    rep = json.loads(report.read_text())["joints"]
    assert [rep[n]["position_offset"] for n in URDF_ORDER] == expected
    assert [rep[n]["homing_offset"] for n in URDF_ORDER] == [
        d * o for d, o in zip(UPSTREAM_DIRS, expected, strict=True)
    ]
    assert rep["leg_left_hip_roll_joint"]["stop"] == "lower"
    assert rep["leg_left_hip_roll_joint"]["stop_angle"] == float(np.deg2rad(-10))
    assert "method: one-sided, robot bhl_biped" in capsys.readouterr().out


def test_one_sided_is_the_default_for_bhl_biped_and_pins_golden_values(tmp_path: Path) -> None:
    rc, out, _ = _sweep(tmp_path, REPLAY)  # robot recognised from the URDF, its procedure is one-sided
    assert rc == 0
    got = _offsets(out)
    assert got[0] == 0.1538167884259858 and got[11] == 0.27525201619594836  # pinned on this replay
    # the joint map robocal reads back gives upstream's q = d*raw - off at every sample
    cal = read_calibration(out, urdf=read_urdf(BIPED_URDF)).calibration
    _, s = _replay()
    raw = s * np.array(UPSTREAM_DIRS)  # identity frame back to raw
    q_upstream = raw * np.array(UPSTREAM_DIRS) - np.array(got)
    np.testing.assert_array_equal(cal.to_joint(raw), q_upstream)


def test_one_sided_to_lite_yaml(tmp_path: Path) -> None:
    rc, out, _ = _sweep(tmp_path, REPLAY, "--robot", "bhl_biped", out="calibration_lite.yaml")
    assert rc == 0 and "position_offsets" in out.read_text()  # the profile's format for a .yaml name
    # the output format follows the profile (berkeley-offsets) unless --format says otherwise
    rc, out2, _ = _sweep(tmp_path, REPLAY, "--robot", "bhl_biped", "--format", "lite-yaml", out="lite.yaml")
    assert rc == 0
    data = YAML(typ="safe").load(out2.read_text())
    offs = upstream_formula(_replay()[1])
    assert [data[n]["homing_offset"] for n in URDF_ORDER] == [
        d * o for d, o in zip(UPSTREAM_DIRS, offs, strict=True)
    ]
    assert data["leg_right_ankle_roll_joint"]["id"] == 14


def test_two_sided_stays_default_for_bimanual(tmp_path: Path) -> None:
    out = tmp_path / "c.yaml"
    outcome = run_sweep(SweepRequest(BIMANUAL_URDF, "sim:lite?seed=3", out, max_samples=50))
    assert outcome.method == "two-sided" and outcome.robot == "bhl_arms"


def _edited_replay(tmp_path: Path, joint: str, fn: object) -> Path:
    names, s = _replay()
    i = names.index(joint)
    s[:, i] = fn(s[:, i])  # type: ignore[operator]
    p = tmp_path / "edited.csv"
    t = np.arange(len(s)) / 20.0
    with open(p, "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(["t", *names])
        for k in range(len(s)):
            w.writerow([repr(float(t[k])), *[repr(float(v)) for v in s[k]]])
    return p


def test_flipped_direction_reaches_the_wrong_side(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """A flipped direction: the joint is pushed into its lower stop but s only goes up from its start."""
    rec = _edited_replay(tmp_path, "leg_left_knee_pitch_joint", lambda c: 2 * c[0] - c)
    rc, _, report = _sweep(tmp_path, rec, "--robot", "bhl_biped")
    err = capsys.readouterr().err
    assert rc == 1
    assert json.loads(report.read_text())["joints"]["leg_left_knee_pitch_joint"]["warnings"] == ["wrong_side"]
    assert "leg_left_knee_pitch_joint: wrong_side" in err


def test_joint_not_moved_is_not_swept(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    rec = _edited_replay(tmp_path, "leg_right_hip_yaw_joint", lambda c: np.full_like(c, c[0]))
    rc, out, _ = _sweep(tmp_path, rec, "--robot", "bhl_biped")
    assert rc == 2 and not out.exists()
    assert (
        "not swept and no prior offset: leg_right_hip_yaw_joint (swept 0.000 rad)" in capsys.readouterr().err
    )


def test_both_stops_report_both_rules_and_their_difference(tmp_path: Path) -> None:
    """A knee swept over its whole URDF range: both rules apply; a stop angle 2 deg off shows as 2 deg."""
    lo, up = read_urdf(BIPED_URDF).limits("leg_left_knee_pitch_joint")
    names, _ = _replay()
    i = names.index("leg_left_knee_pitch_joint")
    off = _offsets(UPSTREAM_CAL)[3]  # q = s - off
    rec = _edited_replay(tmp_path, names[i], lambda c: np.linspace(lo, up, len(c)) + off)
    rows = "".join(
        f"  - {{name: {n}, direction: {d}, stop: {'lower' if side == 'min' else 'upper'}, "
        f"stop_deg: {deg + (2 if n == names[i] else 0)}}}\n"
        for n, d, side, deg in zip(URDF_ORDER, UPSTREAM_DIRS, UPSTREAM_SIDE, UPSTREAM_IDEAL_DEG, strict=True)
    )
    prof = tmp_path / "mine.yaml"
    prof.write_text("format: robocal-robot-profile\nversion: 1\nname: mine\nposition_wraps: false\n"
                    "calibration: {method: one-sided, file_format: berkeley-offsets}\njoints:\n" + rows)  # fmt: skip
    rc, _, report = _sweep(tmp_path, rec, "--robot", str(prof))
    assert rc == 0
    rep = json.loads(report.read_text())["joints"]
    knee = rep["leg_left_knee_pitch_joint"]
    assert knee["rules"]["difference"] == pytest.approx(math.radians(2), abs=1e-12)
    assert knee["rules"]["difference"] == pytest.approx(
        -1 * (knee["rules"]["two_sided_homing_offset"] - knee["rules"]["one_sided_homing_offset"]), abs=0
    )
    assert (
        knee["homing_offset"] == knee["rules"]["one_sided_homing_offset"]
    )  # one-sided method wrote this one
    assert "rules" not in rep["leg_left_hip_roll_joint"]  # one stop only
    # the same sweep two-sided: bisection written, both rules still reported
    rc, _, report = _sweep(tmp_path, rec, "--robot", str(prof), "--method", "two-sided", "--threshold", "0.1")
    assert rc == 1  # the other joints were pushed into one stop only: span_mismatch
    knee2 = json.loads(report.read_text())["joints"]["leg_left_knee_pitch_joint"]
    assert knee2["homing_offset"] == knee["rules"]["two_sided_homing_offset"]
    assert knee2["rules"] == knee["rules"]


def test_one_sided_needs_stops_and_recoil_is_not_robstride(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "c.yaml"
    rc = main(
        [
            "sweep",
            "--urdf",
            str(BIMANUAL_URDF),
            "--source",
            "sim:lite",
            "--out",
            str(out),
            "--method",
            "one-sided",
        ]
    )
    err = capsys.readouterr().err
    assert (
        rc == 2 and "--method one-sided needs the stop each joint is pushed into" in err and not out.exists()
    )
    assert "profile bhl_arms has none for them" in err
    rc = main(["sweep", "--urdf", str(BIPED_URDF), "--source", "can:virtual:x", "--out", str(out)])
    err = capsys.readouterr().err
    assert rc == 2 and "robot bhl_biped has recoil actuators" in err and "replay:FILE" in err
    rc = main(
        [
            "sweep",
            "--urdf",
            str(BIPED_URDF),
            "--source",
            f"replay:{REPLAY}",
            "--out",
            str(out),
            "--method",
            "both",
        ]
    )
    assert rc == 2 and "--method 'both': expected one of one-sided, two-sided" in capsys.readouterr().err


def test_live_view_tells_which_stop_to_push_into() -> None:
    urdf = read_urdf(BIPED_URDF)
    from robocal.formats.profiles import load_profile

    profile = load_profile("bhl_biped")
    joints = joints_from_urdf(urdf, profile)
    stops = [(profile.joint(j.name).stop, profile.joint(j.name).stop_rad) for j in joints]
    session = SweepSession(
        open_source(f"replay:{REPLAY}", joints), joints, method="one-sided", stops=stops, wraps=False
    )  # type: ignore[arg-type]
    buf = io.StringIO()
    view = LiveView(Console(file=buf, width=200, force_terminal=False), period_s=0.0)
    while session.step():
        view.update(session)
    text = buf.getvalue()
    assert "one-sided sweep: push each joint into this stop" in text
    assert "leg_left_hip_roll_joint: lower stop (-10.00°)" in text
    assert "leg_right_ankle_roll_joint: upper stop (+15.00°)" in text
    assert "12/12 joints moved" in text
    table = io.StringIO()
    Console(file=table, width=250).print(view.table(session))
    rendered = table.getvalue()
    assert "push into" in rendered and "upper stop (+33.75°)" in rendered and "wrong_side" not in rendered


def test_core_rule_golden() -> None:
    # one joint, lower stop at -10 deg, samples 0.3 .. -0.02: offset = min - deg2rad(-10)
    off = one_sided_position_offset([-0.02], [0.3], ["lower"], [np.deg2rad(-10)])
    assert off[0] == -0.02 - np.deg2rad(-10)
    r = analyse_sweep(["j"], [-1], [-0.2], [1.5], [-0.02], [0.3], method="one-sided", stops=["lower"],
                      stop_rad=[np.deg2rad(-10)], first=[0.3], threshold_rad=0.05, wraps=False)  # fmt: skip
    assert r["j"].homing_offset == -off[0] and r["j"].warnings == ()


def test_recording_with_the_codes_joint_names(tmp_path: Path) -> None:
    """A recording made with the low-level code names its columns as the code does (left_hip_roll_joint)."""
    text = REPLAY.read_text().splitlines()
    text[0] = "t," + ",".join(n[len("leg_") :] for n in URDF_ORDER)
    rec = tmp_path / "upstream_names.csv"
    rec.write_text("\n".join(text) + "\n")
    rc, out, _ = _sweep(tmp_path, rec)
    assert rc == 0 and _offsets(out) == _offsets(UPSTREAM_CAL)
