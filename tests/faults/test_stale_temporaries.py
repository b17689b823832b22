"""A run killed mid-write leaves its ``.rc-<pid>-*.tmp``; the next write in that folder removes it (issue 26 item 6).

Only the temporary files of robocal processes that no longer exist are removed: a live writer's, another shape of
name, a symbolic link are left alone.
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from robocal.fileio import atomic_write_text, remove_stale_temporaries

from .conftest import SRC

_WRITER = """
import os, sys, time
from robocal.fileio import atomic_write_text
marker = sys.argv[2]
real_fsync = os.fsync
def held_fsync(fd):
    real_fsync(fd)
    with open(marker, "w") as fh:
        fh.write("in the write")
    time.sleep(120)  # SIGKILL lands here: the temporary file is complete, not yet renamed
os.fsync = held_fsync
atomic_write_text(sys.argv[1], "new: 2\\n")
"""


def _writer_held_in_fsync(target: Path) -> subprocess.Popen[bytes]:
    marker = target.with_name("marker")
    proc = subprocess.Popen(
        [sys.executable, "-c", _WRITER, str(target), str(marker)], env=dict(os.environ, PYTHONPATH=str(SRC))
    )
    deadline = time.monotonic() + 120  # hang guard
    while not (marker.exists() and marker.read_text()):
        assert proc.poll() is None, f"the writer exited {proc.returncode} before its write"
        assert time.monotonic() < deadline, "the writer did not reach its write in 120 s"
        time.sleep(0.01)
    marker.unlink()
    return proc


def _temporaries(folder: Path) -> list[str]:
    return sorted(p.name for p in folder.iterdir() if p.name.startswith(".rc-"))


def test_sigkill_during_a_write_then_the_next_write_removes_the_temporary(tmp_path: Path) -> None:
    target = tmp_path / "cal.yaml"
    target.write_text("old: 1\n")
    proc = _writer_held_in_fsync(target)
    left = _temporaries(tmp_path)
    assert len(left) == 1 and left[0].startswith(f".rc-{proc.pid}-") and left[0].endswith(".tmp")
    proc.send_signal(signal.SIGKILL)
    assert proc.wait(timeout=120) == -signal.SIGKILL
    assert target.read_text() == "old: 1\n" and _temporaries(tmp_path) == left  # the kill left it
    atomic_write_text(tmp_path / "other.yaml", "x: 1\n")  # the next write in that folder
    assert _temporaries(tmp_path) == []
    assert target.read_text() == "old: 1\n" and (tmp_path / "other.yaml").read_text() == "x: 1\n"


@pytest.mark.slow
def test_a_live_writers_temporary_is_left_alone(tmp_path: Path) -> None:
    target = tmp_path / "cal.yaml"
    proc = _writer_held_in_fsync(target)
    try:
        left = _temporaries(tmp_path)
        assert remove_stale_temporaries(tmp_path) == []
        atomic_write_text(tmp_path / "other.yaml", "x: 1\n")
        assert _temporaries(tmp_path) == left
    finally:
        proc.kill()
        proc.wait(timeout=120)
    assert [p.name for p in remove_stale_temporaries(tmp_path)] == left


def test_only_regular_files_named_like_ours_are_removed(tmp_path: Path) -> None:
    dead = _dead_pid()
    names = {
        f".rc-{dead}-abcd_123.tmp": True,  # ours, its process gone
        f".rc-{dead}-abc.tmp": False,  # not mkstemp's 8 characters
        ".rc-abcdefgh.tmp": False,  # an older robocal's name: no pid to check
        f".rc-{dead}-abcdefgh.tmp.keep": False,
        f"rc-{dead}-abcdefgh.tmp": False,
        f".rc-{os.getpid()}-abcdefgh.tmp": False,  # this process's own
    }
    for name in names:
        (tmp_path / name).write_text("x")
    link = tmp_path / f".rc-{dead}-linklink.tmp"
    link.symlink_to(tmp_path / ".rc-abcdefgh.tmp")
    removed = {p.name for p in remove_stale_temporaries(tmp_path)}
    assert removed == {n for n, gone in names.items() if gone}
    assert link.is_symlink() and all((tmp_path / n).exists() for n, gone in names.items() if not gone)


def _dead_pid() -> int:
    """The pid of a process that has exited and been reaped (no process has it now)."""
    proc = subprocess.Popen([sys.executable, "-c", "pass"])
    proc.wait(timeout=120)
    try:
        os.kill(proc.pid, 0)
    except ProcessLookupError:
        return proc.pid
    raise AssertionError(f"pid {proc.pid} was reused at once")  # practically never
