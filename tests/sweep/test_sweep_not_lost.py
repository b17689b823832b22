"""Long manual work is never lost: outputs are checked before the sweep, and a failed write shows the offsets."""

from __future__ import annotations

import json
import shutil
import subprocess
import sys
from pathlib import Path
from typing import Any

import pytest
from ruamel.yaml import YAML

from robocal.backends.sim.lite import SimLite
from robocal.cli.main import main
from robocal.errors import FileWriteError
from robocal.formats import read_calibration
from robocal.workflows.sweep import job as wf
from robocal.workflows.sweep.job import SweepRequest, run_sweep
from robocal.workflows.sweep.output import SweepNotSavedError

ELBOW = "left_elbow_pitch"


def _can_mount_read_only(tmp_path: Path) -> bool:
    if shutil.which("unshare") is None:
        return False
    probe = tmp_path / "probe"
    probe.mkdir()
    script = f"mount --bind {probe} {probe} && mount -o remount,ro,bind {probe} && ! touch {probe}/x"
    p = subprocess.run(["unshare", "-m", "sh", "-c", script], capture_output=True, timeout=30)
    return p.returncode == 0


@pytest.mark.slow
@pytest.mark.parametrize("flag", ["--out", "--report"])
def test_read_only_folder_is_refused_before_the_sweep_starts(urdf: Path, tmp_path: Path, flag: str) -> None:
    # a real read-only file system (a read-only bind mount in a private mount namespace): as root, a chmod'ed
    # folder is still writable, and the old os.access check let the whole sweep run before failing
    if not _can_mount_read_only(tmp_path):
        pytest.skip("needs unshare -m and mount (root in a container)")
    ro = tmp_path / "ro"
    ro.mkdir()
    (ro / "cal.yaml").write_text(f"{ELBOW}:\n  id: 14\n  direction: -1\n  homing_offset: 0.73\n")
    rw = tmp_path / "rw"
    rw.mkdir()
    out = ro / "cal.yaml" if flag == "--out" else rw / "cal.yaml"
    report = ro / "report.json" if flag == "--report" else rw / "report.json"
    code = (
        "import sys; from robocal.cli.main import main; "
        "sys.exit(main(['sweep', '--urdf', sys.argv[1], '--source', 'sim:lite', '--out', sys.argv[2], "
        "'--report', sys.argv[3]]))"
    )
    script = (
        f'mount --bind "{ro}" "{ro}" && mount -o remount,ro,bind "{ro}" && '
        f'exec "{sys.executable}" -c "$0" "{urdf}" "{out}" "{report}"'
    )
    p = subprocess.run(
        ["unshare", "-m", "sh", "-c", script, code], capture_output=True, text=True, timeout=120
    )
    assert p.returncode == 2, p.stderr
    lines = p.stderr.splitlines()
    assert len(lines) == 1 and lines[0].startswith(f"error: {flag} {ro}/"), p.stderr
    assert "read-only" in lines[0].lower()
    assert "sweep:" not in p.stderr and p.stdout == ""  # refused before a single sample was read
    assert not (rw / "cal.yaml").exists() and not (rw / "report.json").exists()
    assert (ro / "cal.yaml").read_text().endswith("homing_offset: 0.73\n")


def test_unwritable_output_is_refused_before_the_source_opens(
    urdf: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    # the preflight is fileio.check_output_path's real probe; simulate the read-only file system it meets
    import tempfile

    real = tempfile.mkstemp
    ro = tmp_path / "ro"
    ro.mkdir()

    def mkstemp(*a: Any, **k: Any) -> Any:
        if Path(str(k.get("dir", ""))) == ro:
            raise OSError(30, "Read-only file system")
        return real(*a, **k)

    monkeypatch.setattr(tempfile, "mkstemp", mkstemp)
    opened: list[Any] = []
    with pytest.raises(FileWriteError, match=r"--out .*ro/cal.yaml: cannot write in .*Read-only file system"):
        run_sweep(
            SweepRequest(
                urdf,
                "sim:lite",
                ro / "cal.yaml",
            ),
            open_source_fn=lambda *a, **k: opened.append(1),
        )
    assert opened == []


def _fail_calibration_write(monkeypatch: pytest.MonkeyPatch) -> None:
    def no_space(path: Any, *a: Any, **k: Any) -> str:
        raise FileWriteError(f"cannot write {path}: No space left on device")

    monkeypatch.setattr(wf, "write_calibration", no_space)


@pytest.mark.slow
def test_failed_write_at_the_end_prints_the_offsets(
    urdf: Path, tmp_path: Path, h: Any, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    out, rep = tmp_path / "cal.yaml", tmp_path / "rep.json"
    out.write_text(f"{ELBOW}:\n  id: 14\n  direction: -1\n  homing_offset: 0.73\n")
    before = out.read_text()
    monkeypatch.setattr(wf, "open_source", h.sim_opener(SimLite(5)))
    _fail_calibration_write(monkeypatch)
    rc = main(["sweep", "--urdf", str(urdf), "--source", "sim:lite", "--out", str(out), "--report", str(rep)])
    cap = capsys.readouterr()
    assert rc == 2
    errors = [x for x in cap.err.splitlines() if x.startswith("error:")]
    assert len(errors) == 1 and "No space left on device" in errors[0]
    assert f"{rep} was written; {out} was NOT written (unchanged)" in errors[0]
    assert out.read_text() == before
    report = json.loads(rep.read_text())["joints"]
    # the calibration that could not be written is on standard output, every digit, readable as lite-yaml
    text = cap.out[cap.out.index(f"{h.names[0]}:\n") :]
    printed = YAML(typ="safe").load(text)
    assert list(printed) == h.names
    for name, entry in printed.items():
        assert entry["homing_offset"] == report[name]["homing_offset"]  # exact: repr round trip
        assert entry["direction"] == h.dirs[name]
    assert printed[ELBOW]["id"] == 14
    assert "sweep result" in cap.out  # and the table


@pytest.mark.slow
def test_failed_write_of_lite_json_prints_json(
    urdf: Path, tmp_path: Path, h: Any, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "cal.json"
    monkeypatch.setattr(wf, "open_source", h.sim_opener(SimLite(5)))
    _fail_calibration_write(monkeypatch)
    assert main(["sweep", "--urdf", str(urdf), "--source", "sim:lite", "--out", str(out)]) == 2
    text = capsys.readouterr().out
    printed = json.loads(text[text.index("{\n") :])
    assert set(printed) == set(h.names) and not out.exists()


@pytest.mark.slow
def test_not_saved_error_carries_the_calibration_for_api_users(
    urdf: Path, tmp_path: Path, h: Any, monkeypatch: pytest.MonkeyPatch
) -> None:
    _fail_calibration_write(monkeypatch)
    sim = SimLite(5)
    with pytest.raises(SweepNotSavedError) as info:
        run_sweep(SweepRequest(urdf, "sim:lite", tmp_path / "cal.yaml"), open_source_fn=h.sim_opener(sim))
    err = info.value
    assert err.exit_code == 2 and err.fmt == "lite-yaml" and err.written == ()
    printed = YAML(typ="safe").load(err.calibration_text)
    truth = sim.true_offsets()
    assert all(abs(printed[n]["homing_offset"] - truth[n]) < 2e-3 for n in h.names)


def test_missing_offset_still_prints_the_swept_joints(
    urdf: Path, tmp_path: Path, h: Any, capsys: pytest.CaptureFixture[str]
) -> None:
    from tests.sweep.test_sweep_cli import csv_sweep, elbow

    rec = tmp_path / "sweep.csv"
    csv_sweep(rec, h.names, h.dirs, {ELBOW: elbow(-1.3, -1.0)})
    out = tmp_path / "cal.yaml"
    assert main(["sweep", "--urdf", str(urdf), "--source", f"replay:{rec}", "--out", str(out)]) == 2
    cap = capsys.readouterr()
    assert not out.exists()
    text = cap.out[cap.out.index(f"{h.names[0]}:\n") :]
    printed = YAML(typ="safe").load(text)
    assert ELBOW not in printed and len(printed) == 13
    assert all(printed[n]["homing_offset"] == pytest.approx(0.3 * h.dirs[n]) for n in printed)
    # saved, it is the --prior that completes the next sweep
    prior = tmp_path / "prior.yaml"
    prior.write_text(text)
    csv_sweep(rec, h.names, h.dirs, {ELBOW: elbow(-3.356, -1.0)})
    rc = main(
        ["sweep", "--urdf", str(urdf), "--source", f"replay:{rec}", "--out", str(out), "--prior", str(prior)]
    )
    assert rc == 1  # a replay does not know zero_sta: wrap_in_travel warnings, as in every replay test
    cal = read_calibration(out).calibration
    assert cal.homing_offset[cal.index(ELBOW)] == pytest.approx(1.0)
