"""`robocal sweep` and `robocal check --source` on inputs a user can get wrong: nothing written, one error line."""

from __future__ import annotations

import dataclasses
import json
import math
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from robocal.backends.sim.lite import LITE_JOINTS
from robocal.cli.main import main
from robocal.errors import UsageError
from robocal.formats import read_calibration
from robocal.workflows.sweep.job import SweepRequest

FULL_CSV = "full.csv"


def _full_sweep(tmp: Path) -> Path:
    """Identity-frame CSV sweeping every joint over its URDF span around dir·h = 0.3."""
    cols = [
        0.3 + np.concatenate([np.linspace(j.lower, j.upper, 50), np.linspace(j.upper, j.lower, 50)])
        for j in LITE_JOINTS
    ]
    rows = ["t," + ",".join(j.name for j in LITE_JOINTS)]
    rows += [",".join(repr(float(x)) for x in (0.02 * i, *(c[i] for c in cols))) for i in range(100)]
    p = tmp / FULL_CSV
    p.write_text("\n".join(rows) + "\n")
    return p


def _run(argv: list[str], capsys: pytest.CaptureFixture[str]) -> tuple[int, str]:
    rc = main(argv)
    err = capsys.readouterr().err
    assert "Traceback" not in err
    return rc, err


def _one_error(err: str) -> str:
    lines = [ln for ln in err.splitlines() if ln.startswith("error:")]
    assert len(lines) == 1, err
    return lines[0]


@pytest.mark.parametrize(
    ("content", "fmt", "message"),
    [
        ('{"position_offsets": [0.1, 0.2]}\n', None, "is not a lite-yaml calibration file"),
        ("garbage: [\n", None, "is not a lite-yaml calibration file"),
        (
            "left_elbow_pitch:\n  id: 14\n  direction: -1\n  homing_offset: 0.0\n",
            "lite-json",
            "not a lite-json",
        ),
    ],
    ids=["berkeley", "malformed", "yaml-as-json"],
)
def test_out_existing_in_another_format_is_left_alone(
    content: str, fmt: str | None, message: str, urdf: Path, tmp_path: Path, capsys: Any
) -> None:
    rec = _full_sweep(tmp_path)
    out = tmp_path / "calibration.yaml"
    out.write_text(content)
    extra = ["--format", fmt] if fmt else []
    rc, err = _run(
        ["sweep", "--urdf", str(urdf), "--source", f"replay:{rec}", "--out", str(out), *extra], capsys
    )
    assert rc == 2 and message in _one_error(err) and str(out) in _one_error(err)
    assert out.read_text() == content and not (tmp_path / "calibration.yaml.bak").exists()


def test_out_with_only_comments_counts_as_new(urdf: Path, tmp_path: Path, capsys: Any) -> None:
    rec = _full_sweep(tmp_path)
    out = tmp_path / "calibration.yaml"
    out.write_text("# to be filled by robocal sweep\n")
    rc, _ = _run(["sweep", "--urdf", str(urdf), "--source", f"replay:{rec}", "--out", str(out)], capsys)
    assert rc in (0, 1) and read_calibration(out).calibration.joint_names == tuple(
        j.name for j in LITE_JOINTS
    )


def test_lite_json_in_place_keeps_order_and_other_joints(urdf: Path, tmp_path: Path, capsys: Any) -> None:
    rec = _full_sweep(tmp_path)
    out = tmp_path / "calibration.json"
    old = {"neck_yaw": {"id": 31, "direction": 1, "homing_offset": 0.5}}
    old.update(
        {j.name: {"id": j.can_id, "direction": j.direction, "homing_offset": 0.0} for j in LITE_JOINTS[::-1]}
    )
    out.write_text(json.dumps(old, indent=4) + "\n")
    rc, _ = _run(["sweep", "--urdf", str(urdf), "--source", f"replay:{rec}", "--out", str(out)], capsys)
    assert rc in (0, 1)
    new = json.loads(out.read_text())
    assert list(new) == list(old)  # same joints, same order
    assert new["neck_yaw"] == {"id": 31, "direction": 1, "homing_offset": 0.5}
    elbow = new["left_elbow_pitch"]
    assert elbow["id"] == 14 and elbow["direction"] == -1 and elbow["homing_offset"] == pytest.approx(-0.3)


def test_out_with_other_joint_on_a_urdf_can_id_is_refused(urdf: Path, tmp_path: Path, capsys: Any) -> None:
    rec = _full_sweep(tmp_path)
    out = tmp_path / "calibration.yaml"
    text = "neck_yaw:\n  id: 14\n  direction: 1\n  homing_offset: 0.5\n"
    out.write_text(text)
    rc, err = _run(["sweep", "--urdf", str(urdf), "--source", f"replay:{rec}", "--out", str(out)], capsys)
    assert rc == 2 and "'neck_yaw' (not in the URDF) has CAN id 14" in _one_error(err)
    assert out.read_text() == text


def test_report_same_file_as_out(urdf: Path, tmp_path: Path, capsys: Any) -> None:
    rec = _full_sweep(tmp_path)
    out = tmp_path / "c.yaml"
    rc, err = _run(
        ["sweep", "--urdf", str(urdf), "--source", f"replay:{rec}", "--out", str(out), "--report", str(out)],
        capsys,
    )
    assert rc == 2 and "is the same file as --out" in _one_error(err) and not out.exists()


@pytest.mark.parametrize(
    ("edit", "message"),
    [
        (('<param name="can_id">14</param>', '<param name="can_id">13</param>'), "share CAN id 13"),
        # renamed so that no robot profile (bhl_arms would give id 14) is recognised
        (
            ('<param name="can_id">14</param>', "", '"left_elbow_pitch"', '"left_elbow"'),
            "no <param name='can_id'> for left_elbow",
        ),
    ],
    ids=["duplicate-id", "missing-id"],
)
def test_urdf_ids_checked_before_sampling(
    edit: tuple[str, ...],
    message: str,
    urdf: Path,
    tmp_path: Path,
    capsys: Any,
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    from robocal.workflows.sweep import job as wf

    bad = tmp_path / "bad.urdf"
    text = urdf.read_text()
    for old, new in zip(edit[::2], edit[1::2], strict=True):
        text = text.replace(old, new)
    bad.write_text(text)
    opened: list[Any] = []
    monkeypatch.setattr(wf, "open_source", lambda *a, **k: opened.append(a))
    rc, err = _run(
        ["sweep", "--urdf", str(bad), "--source", "sim:lite", "--out", str(tmp_path / "c.yaml")], capsys
    )
    assert rc == 2 and message in _one_error(err)
    assert opened == [] and not (tmp_path / "c.yaml").exists()  # no sweep was wasted


def test_unwritable_out_folder_is_refused_up_front(
    urdf: Path, tmp_path: Path, capsys: Any, monkeypatch: pytest.MonkeyPatch
) -> None:
    import tempfile

    rec = _full_sweep(tmp_path)
    locked = tmp_path / "locked"
    locked.mkdir()
    real = tempfile.mkstemp

    def mkstemp(*a: Any, **k: Any) -> Any:  # the preflight's probe file meets a folder it may not write in
        if Path(str(k.get("dir", ""))) == locked:
            raise PermissionError(13, "Permission denied")
        return real(*a, **k)

    monkeypatch.setattr(tempfile, "mkstemp", mkstemp)
    out = locked / "c.yaml"
    rc, err = _run(["sweep", "--urdf", str(urdf), "--source", f"replay:{rec}", "--out", str(out)], capsys)
    assert rc == 2 and "permission denied" in _one_error(err).lower() and not out.exists()


def test_write_failure_is_one_error_line(
    urdf: Path, tmp_path: Path, capsys: Any, monkeypatch: pytest.MonkeyPatch
) -> None:
    from robocal.workflows.sweep import job as wf

    rec = _full_sweep(tmp_path)

    def fail(*_: Any, **__: Any) -> None:
        raise PermissionError(13, "Permission denied", str(tmp_path / "c.yaml"))

    monkeypatch.setattr(wf, "write_calibration", fail)
    rc, err = _run(
        ["sweep", "--urdf", str(urdf), "--source", f"replay:{rec}", "--out", str(tmp_path / "c.yaml")], capsys
    )
    out = tmp_path / "c.yaml"
    assert rc == 2 and _one_error(err) == (
        f"error: cannot write {out}: Permission denied; {out} was NOT written (unchanged). The computed "
        "calibration is printed above: save it as a lite-yaml file so the sweep is not lost"
    )


def test_recording_with_absurd_position(urdf: Path, tmp_path: Path, capsys: Any) -> None:
    rec = tmp_path / "r.csv"
    rec.write_text("t,left_elbow_pitch\n0,1e308\n1,-1e308\n")
    rc, err = _run(
        ["sweep", "--urdf", str(urdf), "--source", f"replay:{rec}", "--out", str(tmp_path / "c.yaml")], capsys
    )
    assert rc == 2 and "line 2: left_elbow_pitch is 1e+308 rad" in _one_error(err)
    assert "RuntimeWarning" not in err


def test_check_bad_source_fails_before_printing(urdf: Path, tmp_path: Path, capsys: Any) -> None:
    rec = _full_sweep(tmp_path)
    cal = tmp_path / "c.yaml"
    assert main(["sweep", "--urdf", str(urdf), "--source", f"replay:{rec}", "--out", str(cal)]) in (0, 1)
    capsys.readouterr()
    for extra, message in (
        (["--source", "bogus"], "--source 'bogus'"),
        (["--source", "sim:lite", "--frame", "x"], "error: --frame 'x': expected one of identity, motor"),
    ):
        rc = main(["check", "--urdf", str(urdf), "--calibration", str(cal), *extra])
        captured = capsys.readouterr()
        assert rc == 2 and message in _one_error(captured.err)
        assert captured.out == ""


def test_check_source_with_a_partial_calibration(urdf: Path, tmp_path: Path, capsys: Any) -> None:
    cal = tmp_path / "c.yaml"
    cal.write_text("left_elbow_pitch:\n  id: 14\n  direction: -1\n  homing_offset: 0.0\n")
    rc = main(
        ["check", "--urdf", str(urdf), "--calibration", str(cal), "--source", "sim:lite?seed=3&noise=0"]
    )
    captured = capsys.readouterr()
    assert rc == 1 and "error:" not in captured.err
    assert "joints missing from the calibration file" in captured.err
    assert captured.out.count(": q = ") == 1 and "left_elbow_pitch: q = " in captured.out


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"threshold_rad": math.nan}, "--threshold nan: expected a finite number of rad >= 0"),
        ({"span_tolerance_rad": -0.1}, "--span-tolerance -0.1: expected a finite number of rad >= 0"),
        ({"method": "three-sided"}, "--method 'three-sided': expected one of "),
        ({"direction_step_s": 0.0}, "--direction-time 0.0: expected a finite number of seconds > 0"),
    ],
)
def test_a_sweep_request_is_checked_where_it_is_built(
    tmp_path: Path, kwargs: dict[str, Any], message: str
) -> None:
    with pytest.raises(UsageError) as info:
        SweepRequest("lite.urdf", "sim:lite", tmp_path / "c.yaml", **kwargs)
    assert str(info.value).startswith(message)
    assert list(tmp_path.iterdir()) == []  # nothing opened or written


def test_a_sweep_request_is_a_frozen_value_with_its_numbers_as_floats(tmp_path: Path) -> None:
    request = SweepRequest("lite.urdf", "sim:lite", tmp_path / "c.yaml", threshold_rad=1, span_tolerance_rad=0)
    assert (request.threshold_rad, request.span_tolerance_rad) == (1.0, 0.0)
    assert isinstance(request.threshold_rad, float) and isinstance(request.span_tolerance_rad, float)
    with pytest.raises(dataclasses.FrozenInstanceError):
        request.source = "sim:lite?seed=2"  # type: ignore[misc]
