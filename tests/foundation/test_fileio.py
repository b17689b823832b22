from __future__ import annotations

import os
from pathlib import Path

import pytest

from robocal.errors import FileFormatError, UsageError
from robocal.fileio import atomic_write_text, backup_path, read_text


def test_atomic_write_keeps_backup_and_mode(tmp_path: Path) -> None:
    path = tmp_path / "f.yaml"
    old_mask = os.umask(0o022)
    try:
        atomic_write_text(path, "one\n")
    finally:
        os.umask(old_mask)
    assert (path.stat().st_mode & 0o777) == 0o644  # a new file gets 0666 & ~umask, not mkstemp's 0600
    assert not backup_path(path).exists()
    os.chmod(path, 0o640)
    atomic_write_text(path, "two\n")
    assert path.read_text() == "two\n"
    assert backup_path(path).read_text() == "one\n"
    assert (path.stat().st_mode & 0o777) == 0o640
    assert sorted(p.name for p in tmp_path.iterdir()) == ["f.yaml", "f.yaml.bak"]


@pytest.mark.skipif(os.geteuid() == 0, reason="root ignores directory permissions")
def test_read_only_folder_is_a_clear_error(tmp_path: Path) -> None:
    os.chmod(tmp_path, 0o500)
    try:
        with pytest.raises(UsageError, match="cannot write"):
            atomic_write_text(tmp_path / "x", "x")
    finally:
        os.chmod(tmp_path, 0o700)


def test_failed_write_leaves_old_file_and_no_temp(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    path = tmp_path / "f.json"
    path.write_text("old")

    def boom(*_: object) -> None:
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(os, "fsync", boom)
    with pytest.raises(UsageError, match=r"cannot write .*No space left on device"):
        atomic_write_text(path, "new")
    assert path.read_text() == "old"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["f.json"]


def test_errors_for_missing_folder_directory_and_reads(tmp_path: Path) -> None:
    with pytest.raises(UsageError, match=r"folder .* does not exist"):
        atomic_write_text(tmp_path / "no" / "f", "x")
    with pytest.raises(UsageError, match="it is a directory"):
        atomic_write_text(tmp_path, "x")
    with pytest.raises(FileFormatError, match="no such file"):
        read_text(tmp_path / "absent", "calibration file")
    with pytest.raises(FileFormatError, match="is a directory"):
        read_text(tmp_path, "calibration file")
    (tmp_path / "bin").write_bytes(b"\xff\xfe\x00")
    with pytest.raises(FileFormatError, match="not UTF-8 text"):
        read_text(tmp_path / "bin")
