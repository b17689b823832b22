"""fileio/read.py limits and the CLI's out-of-memory line: big inputs are refused (exit 2) or fit in 1 GiB.

The end-to-end cases run ``robocal`` in a subprocess whose address space is capped at 1 GiB
(``resource.setrlimit(RLIMIT_AS)``), as a small machine or a container would cap it; before the limits, a 64 MB
lite-json of 10⁶ joints ran out of memory there (``MemoryError``, exit 70).
"""

from __future__ import annotations

import contextlib
import os
import subprocess
import sys
import threading
from pathlib import Path

import pytest

from robocal.cli.main import main
from robocal.errors import FileFormatError
from robocal.fileio import MAX_DOCUMENT_BYTES, MAX_URDF_BYTES, read_bytes, read_text

resource = pytest.importorskip("resource")

GIB = 1 << 30


def _run_capped(args: list[str], cwd: Path) -> subprocess.CompletedProcess[str]:
    def cap() -> None:
        resource.setrlimit(resource.RLIMIT_AS, (GIB, GIB))

    return subprocess.run(
        [sys.executable, "-m", "robocal", *args],
        preexec_fn=cap,
        cwd=cwd,
        capture_output=True,
        text=True,
        timeout=600,
    )


def _lite_json(path: Path, joints: int) -> None:
    """A lite-json calibration of ``joints`` joints, written as it streams (ids unique, offsets within ±π)."""
    with path.open("w") as f:
        f.write("{\n")
        for i in range(joints):
            sep = "," if i + 1 < joints else ""
            f.write(
                f'    "joint_{i:07d}": {{\n        "id": {i + 1},\n        "direction": 1,\n'
                f'        "homing_offset": {(i % 600) / 200.0 - 1.5}\n    }}{sep}\n'
            )
        f.write("}\n")


@pytest.mark.slow
def test_a_64_mb_lite_json_of_a_million_joints_is_refused_within_1_gib(tmp_path: Path) -> None:
    big = tmp_path / "calibration.json"
    _lite_json(big, 1_000_000)
    assert big.stat().st_size > 64_000_000
    done = _run_capped(["convert", "calibration.json", "out.yaml", "--to", "lite-yaml"], tmp_path)
    assert done.returncode == 2, done.stderr
    assert done.stderr == (
        f"error: calibration file calibration.json: {big.stat().st_size} bytes is larger than robocal's "
        f"{MAX_DOCUMENT_BYTES} byte (8 MiB) limit for a calibration file\n"
    )
    assert sorted(p.name for p in tmp_path.iterdir()) == ["calibration.json"]


@pytest.mark.slow
def test_a_calibration_just_under_the_limit_converts_within_1_gib(tmp_path: Path) -> None:
    src = tmp_path / "calibration.json"
    joints = 70_000
    _lite_json(src, joints)
    assert MAX_DOCUMENT_BYTES * 0.8 < src.stat().st_size <= MAX_DOCUMENT_BYTES
    done = _run_capped(["convert", "calibration.json", "out.yaml", "--to", "lite-yaml"], tmp_path)
    assert done.returncode == 0, done.stderr
    assert f"{joints} joints" in done.stdout
    assert (tmp_path / "out.yaml").stat().st_size > 0


@pytest.mark.slow
def test_a_urdf_over_its_limit_is_refused_within_1_gib(tmp_path: Path) -> None:
    (tmp_path / "cal.json").write_text('{"j1": {"id": 1, "direction": 1, "homing_offset": 0.0}}\n')
    urdf = tmp_path / "robot.urdf"
    with urdf.open("w") as f:
        f.write('<?xml version="1.0"?>\n<robot name="big">\n<link name="l0"/>\n')
        pad = "<!--" + "x" * 1_000_000 + "-->\n"
        for _ in range(MAX_URDF_BYTES // len(pad) + 1):
            f.write(pad)
        f.write("</robot>\n")
    done = _run_capped(["check", "--calibration", "cal.json", "--urdf", "robot.urdf"], tmp_path)
    assert done.returncode == 2, done.stderr
    assert done.stderr == (
        f"error: URDF robot.urdf: {urdf.stat().st_size} bytes is larger than robocal's {MAX_URDF_BYTES} byte "
        "(16 MiB) limit for a URDF\n"
    )


def test_limits_are_applied_to_pipes_too(tmp_path: Path) -> None:
    """A FIFO reports size 0: it is read up to the limit and refused after one byte more, not read to the end."""
    fifo = tmp_path / "cal.yaml"
    os.mkfifo(fifo)

    def feed() -> None:
        with contextlib.suppress(BrokenPipeError), fifo.open("wb") as w:  # the reader stops early, as it should
            w.write(b"x" * 2000)

    writer = threading.Thread(target=feed, daemon=True)
    writer.start()
    with pytest.raises(FileFormatError) as err:
        read_text(fifo, "calibration file", limit=1000)
    writer.join(60)
    assert str(err.value) == (
        f"calibration file {fifo}: more than 1000 bytes, robocal's 1000 byte (1000 bytes) limit for a calibration file"
    )


def test_a_file_at_the_limit_is_read(tmp_path: Path) -> None:
    p = tmp_path / "a.json"
    p.write_bytes(b"x" * 1000)
    assert read_bytes(p, "calibration file", limit=1000) == b"x" * 1000
    p.write_bytes(b"x" * 1001)
    with pytest.raises(FileFormatError, match=r"1001 bytes is larger than robocal's 1000 byte"):
        read_bytes(p, "calibration file", limit=1000)


def test_out_of_memory_is_one_error_line_exit_2(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    """A MemoryError anywhere in a command (an input no limit covers) is a clean error, not a crash log (70)."""
    import robocal.workflows.files.job as files  # robocal.cli.files imports convert_file when the command runs

    def exhausted(*_: object, **__: object) -> None:
        raise MemoryError

    monkeypatch.setattr(files, "convert_file", exhausted)
    (tmp_path / "a.json").write_text('{"j1": {"id": 1, "direction": 1, "homing_offset": 0.0}}\n')
    code = main(["convert", str(tmp_path / "a.json"), str(tmp_path / "b.yaml")])
    err = capsys.readouterr().err
    assert code == 2
    assert err.count("\n") == 1 and err.startswith("error: robocal convert ran out of memory")
    assert "an input is too large for this machine (robocal's input limits: docs/design.md, Input limits)" in err
    assert "Traceback" not in err and "internal error" not in err
