"""`robocal sweep` through the CLI: constructed sweeps for every diagnostic code, malformed input, demo."""

from __future__ import annotations

import json
import math
import signal
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from robocal.cli.main import main
from robocal.formats import read_calibration

ELBOW = "left_elbow_pitch"  # dir -1, limits [-2.356, 0]


def csv_sweep(path: Path, names: list[str], dirs: dict[str, int], special: dict[str, np.ndarray]) -> None:
    """Identity-frame CSV: every joint swept fully around offset 0.3 (dir·h), ``special`` overrides a joint."""
    from robocal.backends.sim.lite import LITE_JOINTS

    limits = {j.name: (j.lower, j.upper) for j in LITE_JOINTS}
    n = 200
    cols = []
    for name in names:
        if name in special:
            col = special[name]
        else:
            lo, up = limits[name]
            col = 0.3 + np.concatenate([np.linspace(lo, up, n // 2), np.linspace(up, lo, n - n // 2)])
        cols.append(col)
    t = np.arange(n) * 0.02
    rows = ["t," + ",".join(names)] + [
        ",".join(repr(float(x)) for x in (t[i], *(c[i] for c in cols))) for i in range(n)
    ]
    path.write_text("\n".join(rows) + "\n")


def elbow(s_min: float, s_max: float, n: int = 200) -> np.ndarray:
    return np.concatenate([np.linspace(s_max, s_min, n // 2), np.linspace(s_min, s_max, n - n // 2)])


CASES: dict[str, tuple[np.ndarray, list[str], float]] = {
    # code: (elbow identity-frame samples, expected warnings, expected homing_offset)
    "ok": (elbow(-3.356, -1.0), [], 1.0),
    "no_overlap": (elbow(0.5, 2.856), ["no_overlap"], -2.856),
    "span_mismatch": (elbow(-3.056, -1.0), ["span_mismatch"], 0.85),
    "offset_large": (elbow(-6.0, -3.644), ["no_overlap", "offset_large"], 3.644),
    "wrap_in_travel": (elbow(-1.856, 0.5), ["wrap_in_travel"], -0.5),
}


@pytest.mark.slow
@pytest.mark.parametrize("code", list(CASES))
def test_constructed_sweep_for_each_code(
    code: str, urdf: Path, tmp_path: Path, h: Any, capsys: pytest.CaptureFixture[str]
) -> None:
    samples, warnings, offset = CASES[code]
    rec = tmp_path / "sweep.csv"
    csv_sweep(rec, h.names, h.dirs, {ELBOW: samples})
    out, rep = tmp_path / "cal.yaml", tmp_path / "rep.json"
    code_rc = main(
        ["sweep", "--urdf", str(urdf), "--source", f"replay:{rec}", "--out", str(out), "--report", str(rep)]
    )
    report = json.loads(rep.read_text())["joints"]
    assert report[ELBOW]["warnings"] == warnings
    assert report[ELBOW]["homing_offset"] == pytest.approx(offset, abs=1e-9)
    cal = read_calibration(out).calibration
    assert cal.homing_offset[cal.index(ELBOW)] == pytest.approx(offset, abs=1e-9)
    assert all(v["homing_offset"] == pytest.approx(0.3 * h.dirs[k]) for k, v in report.items() if k != ELBOW)
    assert code_rc == (0 if not any(v["warnings"] for v in report.values()) else 1)
    err = capsys.readouterr().err
    for w in warnings:
        assert f"warning: {ELBOW}: {w}" in err


@pytest.mark.slow
def test_not_swept_keeps_prior_and_errors_without(urdf: Path, tmp_path: Path, h: Any, capsys: Any) -> None:
    rec = tmp_path / "sweep.csv"
    csv_sweep(rec, h.names, h.dirs, {ELBOW: elbow(-1.3, -1.0)})
    out = tmp_path / "cal.yaml"
    rc = main(["sweep", "--urdf", str(urdf), "--source", f"replay:{rec}", "--out", str(out)])
    err = capsys.readouterr().err
    assert rc == 2 and not out.exists()
    assert err.count("error:") == 1 and "left_elbow_pitch (swept 0.300 rad)" in err
    prior = tmp_path / "prior.yaml"
    prior.write_text(f"{ELBOW}:\n  id: 14\n  direction: -1\n  homing_offset: 0.75\n")
    rep = tmp_path / "r.json"
    args = [
        "sweep",
        "--urdf",
        str(urdf),
        "--source",
        f"replay:{rec}",
        "--out",
        str(out),
        "--report",
        str(rep),
    ]
    rc = main([*args, "--prior", str(prior)])
    assert rc == 1
    entry = json.loads(rep.read_text())["joints"][ELBOW]
    assert (
        entry["warnings"] == ["not_swept"] and entry["kept_prior"] is True and entry["homing_offset"] == 0.75
    )
    cal = read_calibration(out).calibration
    assert cal.homing_offset[cal.index(ELBOW)] == 0.75


@pytest.mark.slow
def test_direction_flipped_by_guided_check(urdf: Path, tmp_path: Path, capsys: Any) -> None:
    out, rep = tmp_path / "cal.yaml", tmp_path / "r.json"
    src = "sim:lite?seed=4&flip=left_elbow_pitch&noise=0"
    rc = main(
        [
            "sweep",
            "--urdf",
            str(urdf),
            "--source",
            src,
            "--out",
            str(out),
            "--report",
            str(rep),
            "--direction-check",
        ]
    )
    joints = json.loads(rep.read_text())["joints"]
    assert "direction_flipped" in joints[ELBOW]["warnings"]
    assert all("direction_flipped" not in v["warnings"] for k, v in joints.items() if k != ELBOW)
    # the flipped elbow still overlaps its URDF range: the overlap heuristic alone would miss it
    assert "no_overlap" not in joints[ELBOW]["warnings"]
    assert rc == 1 and out.exists()
    assert "direction check: move left_elbow_pitch toward its + limit" in capsys.readouterr().err


@pytest.mark.slow
def test_in_place_update_keeps_comments(urdf: Path, tmp_path: Path) -> None:
    out = tmp_path / "calibration.yaml"
    names = [
        "left_shoulder_pitch", "left_shoulder_roll", "left_shoulder_yaw", "left_elbow_pitch", "left_wrist_yaw",
        "left_wrist_roll", "left_wrist_pitch", "right_shoulder_pitch", "right_shoulder_roll", "right_shoulder_yaw",
        "right_elbow_pitch", "right_wrist_yaw", "right_wrist_roll", "right_wrist_pitch",
    ]  # fmt: skip
    from robocal.backends.sim.lite import LITE_JOINTS

    text = "# my robot, bench 3\n" + "".join(
        f"{j.name}:  # {j.bus}\n  id: {j.can_id}\n  direction: {j.direction}\n  homing_offset: 0.0\n"
        for j in LITE_JOINTS
    )
    out.write_text(text)
    rc = main(["sweep", "--urdf", str(urdf), "--source", "sim:lite?seed=2", "--out", str(out)])
    assert rc in (0, 1)
    new = out.read_text()
    assert new.startswith("# my robot, bench 3\n") and "left_elbow_pitch:  # can0" in new
    assert [line.split(":")[0] for line in new.splitlines() if line and line[0].isalpha()] == names
    assert (tmp_path / "calibration.yaml.bak").read_text() == text
    assert all(h != 0.0 for h in read_calibration(out).calibration.homing_offset)


@pytest.mark.slow
def test_lite_json_output(urdf: Path, tmp_path: Path) -> None:
    out = tmp_path / "calibration.json"
    assert main(["sweep", "--urdf", str(urdf), "--source", "sim:lite?seed=2", "--out", str(out)]) in (0, 1)
    data = json.loads(out.read_text())
    assert data["left_elbow_pitch"]["id"] == 14 and data["left_elbow_pitch"]["direction"] == -1
    assert math.isfinite(data["left_elbow_pitch"]["homing_offset"])


def _bad_csv(tmp: Path) -> Path:
    p = tmp / "bad.csv"
    p.write_text("t,left_elbow_pitch\n0.0,abc\n")
    return p


MALFORMED: list[tuple[str, Any, str]] = [
    ("source", lambda u, t: ["--source", "bogus"], "--source 'bogus': expected sim:lite"),
    ("sim robot", lambda u, t: ["--source", "sim:atlas"], "unknown simulated robot 'atlas'"),
    ("sim option", lambda u, t: ["--source", "sim:lite?speed=3"], "unknown option 'speed'"),
    ("sim seed", lambda u, t: ["--source", "sim:lite?seed=x"], "seed must be a non-negative integer"),
    ("sim skip", lambda u, t: ["--source", "sim:lite?skip=nope"], "skip: unknown joint(s) nope"),
    ("can", lambda u, t: ["--source", "can:socketcan"], "expected can:<interface>:<channel>"),
    ("threshold", lambda u, t: ["--source", "sim:lite", "--threshold", "nan"], "--threshold nan"),
    ("tolerance", lambda u, t: ["--source", "sim:lite", "--span-tolerance", "-1"], "--span-tolerance -1"),
    ("format", lambda u, t: ["--source", "sim:lite", "--format", "xml"], "--format 'xml'"),
    ("frame", lambda u, t: ["--source", "sim:lite", "--frame", "world"], "--frame 'world'"),
    ("replay missing", lambda u, t: ["--source", f"replay:{t}/none.csv"], "no such file or folder"),
    ("replay bad cell", lambda u, t: ["--source", f"replay:{_bad_csv(t)}"], "line 2: a cell is not a number"),
    (
        "replay + check",
        lambda u, t: ["--source", f"replay:{_bad_csv(t)}", "--direction-check"],
        "needs a live",
    ),
    ("prior missing", lambda u, t: ["--source", "sim:lite", "--prior", f"{t}/nope.yaml"], "nope.yaml"),
    ("report dir", lambda u, t: ["--source", "sim:lite", "--report", f"{t}/no/dir.json"], "--report"),
]


@pytest.mark.parametrize(("label", "extra", "message"), MALFORMED, ids=[m[0] for m in MALFORMED])
def test_malformed_input(
    label: str, extra: Any, message: str, urdf: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "cal.yaml"
    before = sorted(p.name for p in tmp_path.iterdir())
    rc = main(["sweep", "--urdf", str(urdf), "--out", str(out), *extra(urdf, tmp_path)])
    err = capsys.readouterr().err
    assert rc == 2, err
    lines = [ln for ln in err.splitlines() if ln.startswith("error:")]
    assert len(lines) == 1 and message in lines[0], err
    assert "Traceback" not in err
    after = sorted(p.name for p in tmp_path.iterdir())
    assert not out.exists() and [p for p in after if p not in before and p != "bad.csv"] == []


def test_malformed_urdf(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    bad = tmp_path / "bad.urdf"
    bad.write_text("<robot name='x'><joint name='j' type='revolute'></robot>")
    rc = main(["sweep", "--urdf", str(bad), "--source", "sim:lite", "--out", str(tmp_path / "c.yaml")])
    assert rc == 2 and capsys.readouterr().err.startswith("error:")
    assert not (tmp_path / "c.yaml").exists()


@pytest.mark.slow
def test_run_demo_recovers_offsets(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["demo", "--out", str(tmp_path)]) == 0
    out = capsys.readouterr().out
    assert "true vs recovered homing_offset" in out and "left_elbow_pitch" in out
    assert (tmp_path / "calibration.yaml").exists() and (tmp_path / "sweep_report.json").exists()
    assert main(["demo"]) == 0


def test_cli_second_ctrl_c_exit_130_writes_nothing(
    urdf: Path, tmp_path: Path, h: Any, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    from robocal.backends.sim.lite import SimLite
    from robocal.workflows.sweep import job as wf

    out = tmp_path / "cal.yaml"
    out.write_text("# keep me\n")
    opener, _ = h.recording_opener(SimLite(31), interrupt_at=20, interrupt_close=True)
    monkeypatch.setattr(wf, "open_source", opener)
    rc = main(["sweep", "--urdf", str(urdf), "--source", "sim:lite", "--out", str(out)])
    err = capsys.readouterr().err
    assert rc == 130
    assert [ln for ln in err.splitlines() if ln.startswith("error:")] == [
        "error: sweep aborted by a second Ctrl-C; nothing was written"
    ]
    assert out.read_text() == "# keep me\n" and not (tmp_path / "cal.yaml.bak").exists()


@pytest.mark.slow
def test_cli_first_ctrl_c_writes(
    urdf: Path, tmp_path: Path, h: Any, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    from robocal.backends.sim.lite import SimLite
    from robocal.workflows.sweep import job as wf

    out = tmp_path / "cal.yaml"
    opener, _ = h.recording_opener(SimLite(32), interrupt_at=250)
    monkeypatch.setattr(wf, "open_source", opener)
    rc = main(["sweep", "--urdf", str(urdf), "--source", "sim:lite", "--out", str(out)])
    assert rc in (0, 1)
    assert read_calibration(out).calibration.joint_names == tuple(h.names)
    assert "wrote" in capsys.readouterr().out


def test_live_view_table_and_plain_lines(urdf: Path, tmp_path: Path, h: Any) -> None:
    import io

    from rich.console import Console

    from robocal.backends.sources import ReplaySource
    from robocal.cli._sweep_view import LiveView
    from robocal.formats.urdf import read_urdf
    from robocal.workflows.sweep.joint_specs import joints_from_urdf
    from robocal.workflows.sweep.session import SweepSession

    joints = joints_from_urdf(read_urdf(urdf))
    n = len(joints)
    pos = np.zeros((3, n))
    pos[:, 3] = [-3.356, -2.0, -1.0]  # elbow swept over its full span
    src = ReplaySource([j.name for j in joints], np.arange(3.0), pos, "identity")
    session = SweepSession(src, joints)
    while session.step():
        pass
    buf = io.StringIO()
    view = LiveView(Console(file=buf, force_terminal=False, width=140), period_s=0.0)
    with view:
        view.update(session)
    assert buf.getvalue() == "sweep: 3 samples, 1/14 joints at full span\n"
    table_buf = io.StringIO()
    Console(file=table_buf, width=160).print(view.table(session))
    text = table_buf.getvalue()
    assert "left_elbow_pitch" in text and "100%" in text and "not_swept" in text


class _StillSource:
    """A 1 kHz source (source clock 1 ms per read) whose joint 0 starts moving + at ``move_at_s``."""

    frame = "identity"
    exhausted = False

    def __init__(self, move_at_s: float) -> None:
        self.joint_names = ("j",)
        self.move_at_s = move_at_s
        self.reads = 0

    def read(self) -> Any:
        from robocal.backends.sources import Sample

        t = self.reads * 1e-3
        self.reads += 1
        return Sample(t, np.array([0.2 + max(0.0, t - self.move_at_s)]))

    def prompt_positive(self, joint: str) -> None:
        pass


def test_direction_check_waits_by_time_not_samples() -> None:
    from robocal.backends.sources import JointSpec
    from robocal.workflows.sweep.session import run_direction_check

    j = [JointSpec("j", 1, "rs-00", 1, -1.0, 1.0)]
    # a person who starts moving 2.5 s after the prompt on a 1 kHz bus (2,500 samples) is still seen
    late = _StillSource(move_at_s=2.5)
    results: list[tuple[str, int]] = []
    assert run_direction_check(late, j, step_s=5.0, on_result=lambda n, v: results.append((n, v))) == {"j": 1}
    assert results == [("j", 1)] and late.reads > 2000
    # a joint that never moves: the wait ends after step_s of source time, verdict 0 (not verified)
    still = _StillSource(move_at_s=1e9)
    assert run_direction_check(still, j, step_s=3.0) == {"j": 0}
    assert still.reads == 3002  # the start sample, 3 s at 1 kHz, and the first sample past the budget


class _Deaf:
    """Wraps a sim source; the simulated operator ignores the direction-check prompt for ``joint``."""

    def __init__(self, inner: Any, joint: str) -> None:
        self.inner, self.joint = inner, joint
        self.joint_names, self.frame = inner.joint_names, inner.frame

    def __getattr__(self, name: str) -> Any:
        return getattr(self.inner, name)

    @property
    def exhausted(self) -> bool:
        return bool(self.inner.exhausted)

    def prompt_positive(self, joint: str) -> None:
        if joint != self.joint:
            self.inner.prompt_positive(joint)


@pytest.mark.slow
def test_direction_unknown_is_reported_when_a_joint_does_not_move(
    urdf: Path, tmp_path: Path, h: Any, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    from robocal.backends.sim.lite import SimLite
    from robocal.workflows.sweep import job as wf

    base = h.sim_opener(SimLite(45, noise_rad=0.0))
    monkeypatch.setattr(wf, "open_source", lambda *a, **k: _Deaf(base(*a, **k), ELBOW))
    out, rep = tmp_path / "cal.yaml", tmp_path / "r.json"
    args = ["--urdf", str(urdf), "--source", "sim:lite", "--out", str(out), "--report", str(rep)]
    rc = main(["sweep", *args, "--direction-check", "--direction-time", "0.5"])
    joints = json.loads(rep.read_text())["joints"]
    assert joints[ELBOW]["warnings"] == ["direction_unknown"]
    others = [set(v["warnings"]) for k, v in joints.items() if k != ELBOW]
    assert all(not {"direction_unknown", "direction_flipped"} & w for w in others)  # the others moved right
    assert rc == 1 and out.exists()
    err = capsys.readouterr().err
    assert f"direction check: {ELBOW}: direction_unknown: did not move 0.1 rad within" in err
    assert (
        f"warning: {ELBOW}: direction_unknown: did not move 0.1 rad within the direction check's time" in err
    )
    # without --direction-check nothing claims a verified or unverified direction
    main(["sweep", *args])
    assert json.loads(rep.read_text())["joints"][ELBOW]["warnings"] == []


def test_direction_time_must_be_positive(
    urdf: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "c.yaml"
    args = ["sweep", "--urdf", str(urdf), "--source", "sim:lite", "--out", str(out), "--direction-time", "0"]
    assert main(args) == 2 and not out.exists()
    assert "error: --direction-time 0.0: expected a finite number of seconds > 0" in capsys.readouterr().err


@pytest.mark.slow
def test_cli_second_ctrl_c_after_the_report_names_it(
    urdf: Path, tmp_path: Path, h: Any, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    from robocal.backends.sim.lite import SimLite
    from robocal.workflows.sweep import job as wf

    out, rep = tmp_path / "cal.yaml", tmp_path / "r.json"
    monkeypatch.setattr(wf, "open_source", h.sim_opener(SimLite(46, noise_rad=0.0)))

    def two_ctrl_c(*a: Any, **k: Any) -> None:  # real SIGINTs: the first only asks the sweep to finish
        signal.raise_signal(signal.SIGINT)
        signal.raise_signal(signal.SIGINT)

    monkeypatch.setattr(wf, "write_calibration", two_ctrl_c)
    rc = main(["sweep", "--urdf", str(urdf), "--source", "sim:lite", "--out", str(out), "--report", str(rep)])
    err = capsys.readouterr().err
    assert rc == 130 and not out.exists() and rep.exists()
    assert [ln for ln in err.splitlines() if ln.startswith("error:")] == [
        f"error: sweep aborted by a second Ctrl-C after writing {rep} (complete); {out} not written (unchanged)"
    ]


def test_cli_notes_skipped_nan_samples(
    urdf: Path, tmp_path: Path, h: Any, capsys: pytest.CaptureFixture[str]
) -> None:
    rec = tmp_path / "sweep.csv"
    samples = elbow(-3.356, -1.0)
    samples[[7, 50, 120]] = np.nan
    csv_sweep(rec, h.names, h.dirs, {ELBOW: samples})
    out, rep = tmp_path / "cal.yaml", tmp_path / "r.json"
    args = ["--source", f"replay:{rec}", "--out", str(out), "--report", str(rep)]
    main(["sweep", "--urdf", str(urdf), *args])
    assert json.loads(rep.read_text())["joints"][ELBOW]["warnings"] == []  # a skipped NaN is not a warning
    assert read_calibration(out).calibration.homing_offset[3] == pytest.approx(1.0, abs=1e-9)
    err = capsys.readouterr().err
    assert f"note: {ELBOW}: 3 of 200 samples had no position (NaN) and were skipped" in err
