"""Backups: five rotating generations, made as atomically as the file itself, also through symbolic links."""

from __future__ import annotations

import errno
import hashlib
import logging
import os
import shutil
from pathlib import Path

import pytest
from fs_sandbox import needs_unshare, run_on_tmpfs

from robocal import fileio
from robocal.errors import FileWriteError
from robocal.fileio import BACKUP_GENERATIONS, atomic_write, atomic_write_text, backup_path, backup_paths


def _names(folder: Path) -> list[str]:
    return sorted(p.name for p in folder.iterdir())


def test_five_generations_rotate_and_the_oldest_is_dropped(tmp_path: Path) -> None:
    path = tmp_path / "cal.yaml"
    for i in range(8):
        atomic_write_text(path, f"v{i}\n")
    assert BACKUP_GENERATIONS == 5
    assert path.read_text() == "v7\n"
    assert [p.name for p in backup_paths(path)] == [
        "cal.yaml.bak",
        "cal.yaml.bak.1",
        "cal.yaml.bak.2",
        "cal.yaml.bak.3",
        "cal.yaml.bak.4",
    ]
    assert [p.read_text() for p in backup_paths(path)] == ["v6\n", "v5\n", "v4\n", "v3\n", "v2\n"]
    assert _names(tmp_path) == ["cal.yaml", *(p.name for p in backup_paths(path))]
    assert backup_path(path) == tmp_path / "cal.yaml.bak"


def test_same_bytes_do_not_use_a_generation(tmp_path: Path) -> None:
    path = tmp_path / "cal.json"
    atomic_write_text(path, "a")
    atomic_write_text(path, "b")
    res = atomic_write(path, b"b")
    assert res.backup is None
    assert _names(tmp_path) == ["cal.json", "cal.json.bak"]
    assert backup_path(path).read_text() == "a"
    assert atomic_write(path, b"c").backup == tmp_path / "cal.json.bak"
    assert [p.read_text() for p in backup_paths(path)[:2]] == ["b", "a"]


def test_backup_false_keeps_the_backups_as_they_are(tmp_path: Path) -> None:
    path = tmp_path / "f"
    atomic_write_text(path, "1")
    atomic_write_text(path, "2")
    atomic_write_text(path, "3", backup=False)
    assert path.read_text() == "3"
    assert _names(tmp_path) == ["f", "f.bak"]
    assert backup_path(path).read_text() == "1"


def test_long_names_get_short_backup_names_that_rotate(tmp_path: Path) -> None:
    name = "L" * 255
    path = tmp_path / name
    for i in range(3):
        atomic_write_text(path, f"v{i}")
    digest = hashlib.sha1(name.encode()).hexdigest()[:8]
    gens = backup_paths(path)
    assert all(len(g.name.encode()) <= 255 for g in gens)
    assert gens[0].name == "L" * (255 - 6 - 9) + "~" + digest + ".bak"
    assert [g.read_text() for g in gens[:2]] == ["v1", "v0"]
    short = tmp_path / ("s" * 249)  # 249 + len(".bak.4") == 255: the plain suffix still fits
    assert backup_path(short).name == "s" * 249 + ".bak"


def test_failed_backup_copy_leaves_the_old_backup_byte_identical(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A file system without hard links: the backup is copied; a full disk mid-copy changes nothing."""
    path = tmp_path / "cal.yaml"
    atomic_write_text(path, "old-backup " * 100)
    atomic_write_text(path, "current " * 1000)
    old_bak = backup_path(path).read_bytes()

    def no_link(*_: object, **__: object) -> None:
        raise OSError(errno.EPERM, "Operation not permitted")

    def half_copy(src: object, dst: object, *_: object) -> None:
        dst.write(src.read(100))  # type: ignore[attr-defined]
        raise OSError(errno.ENOSPC, "No space left on device")

    monkeypatch.setattr(os, "link", no_link)
    monkeypatch.setattr(shutil, "copyfileobj", half_copy)
    with pytest.raises(
        FileWriteError, match=r"cannot write .*cal.yaml: No space left on device; the file and its"
    ):
        atomic_write_text(path, "new")
    assert backup_path(path).read_bytes() == old_bak
    assert path.read_text() == "current " * 1000
    assert _names(tmp_path) == ["cal.yaml", "cal.yaml.bak"]


@needs_unshare
@pytest.mark.parametrize("links", [True, False])
def test_full_disk_never_truncates_the_backup(tmp_path: Path, links: bool) -> None:
    """On a real full tmpfs: with hard links the backup costs no space and the write succeeds; without them
    the copy runs out of space and the file, its backup and the folder are exactly as before."""
    out = run_on_tmpfs(
        tmp_path,
        """
        from robocal.fileio import atomic_write_bytes
        atomic_write_bytes(mnt / "cal.yaml", b"B" * 8000)
        atomic_write_bytes(mnt / "cal.yaml", b"C" * 30000)       # cal.yaml.bak holds the B's
        with open(mnt / "fill", "wb") as fh:                      # leave about 16 KiB free
            fh.write(b"0" * (64 * 1024 - 8192 - 30720 - 16384))
        """,
        f"""
        import hashlib
        from robocal.errors import FileWriteError
        from robocal.fileio import atomic_write_bytes
        if not {links}:
            def no_link(*a, **k):
                raise OSError(1, "Operation not permitted")
            os.link = no_link
        before = {{n: hashlib.sha256((mnt / n).read_bytes()).hexdigest() for n in os.listdir(mnt)}}
        try:
            atomic_write_bytes(mnt / "cal.yaml", b"D" * 2000)
            msg = "written"
        except FileWriteError as exc:
            msg = str(exc)
        after = {{n: hashlib.sha256((mnt / n).read_bytes()).hexdigest() for n in os.listdir(mnt)}}
        print(json.dumps({{"msg": msg, "before": before, "after": after,
                          "cal": (mnt / "cal.yaml").read_bytes()[:1].decode(),
                          "bak": (mnt / "cal.yaml.bak").read_bytes()[:1].decode(),
                          "bak1": (mnt / "cal.yaml.bak.1").read_bytes()[:1].decode()
                                  if (mnt / "cal.yaml.bak.1").exists() else None}}))
        """,
    )
    if links:
        assert out["msg"] == "written"
        assert (out["cal"], out["bak"], out["bak1"]) == ("D", "C", "B")
        assert out["after"]["cal.yaml.bak.1"] == out["before"]["cal.yaml.bak"]
    else:
        assert "No space left on device" in out["msg"] and "unchanged" in out["msg"]
        assert out["after"] == out["before"]  # same names, same bytes: the old .bak is byte-identical


def test_symlink_is_written_through_and_stays_a_link(
    tmp_path: Path, caplog: pytest.LogCaptureFixture
) -> None:
    robot = tmp_path / "robot"
    robot.mkdir()
    target = robot / "calibration.yaml"
    target.write_text("old\n")
    work = tmp_path / "work"
    work.mkdir()
    link = work / "cal.yaml"
    link.symlink_to(Path("..") / "robot" / "calibration.yaml")
    with caplog.at_level(logging.INFO, logger="robocal.fileio"):
        res = atomic_write(link, b"new\n")
    assert link.is_symlink() and os.readlink(link) == str(Path("..") / "robot" / "calibration.yaml")
    assert target.read_text() == "new\n"
    assert res.via_link and res.target == target and res.path == link
    assert res.backup == robot / "calibration.yaml.bak"
    assert (robot / "calibration.yaml.bak").read_text() == "old\n"
    assert _names(work) == ["cal.yaml"]  # no backup or temporary file next to the link
    assert _names(robot) == ["calibration.yaml", "calibration.yaml.bak"]
    assert res.describe() == (
        f"{link} is a symbolic link: wrote its target {target} (previous version kept as {robot}/calibration.yaml.bak)"
    )
    assert [r.getMessage() for r in caplog.records] == [res.describe()]


def test_chain_of_links_and_dangling_link(tmp_path: Path) -> None:
    (tmp_path / "real").write_text("1")
    (tmp_path / "mid").symlink_to("real")
    (tmp_path / "top").symlink_to("mid")
    atomic_write_text(tmp_path / "top", "2")
    assert (tmp_path / "real").read_text() == "2"
    assert (tmp_path / "top").is_symlink() and (tmp_path / "mid").is_symlink()
    assert (tmp_path / "real.bak").read_text() == "1"
    (tmp_path / "dangling").symlink_to("new_target")
    res = atomic_write(tmp_path / "dangling", b"x")
    assert (tmp_path / "new_target").read_bytes() == b"x" and res.backup is None
    assert (tmp_path / "dangling").is_symlink()


def test_lone_surrogate_in_text_is_a_clear_error(tmp_path: Path) -> None:
    with pytest.raises(FileWriteError, match=r"line 2 holds '\\udcff', a lone surrogate"):
        atomic_write_text(tmp_path / "x.yaml", "a: 1\nb\udcff: 2\n")
    assert _names(tmp_path) == []


def test_owner_mode_kept_and_no_temporary_files(tmp_path: Path) -> None:
    path = tmp_path / "f"
    path.write_text("0")
    path.chmod(0o600)
    for i in range(3):
        atomic_write_text(path, str(i + 1))
    assert path.stat().st_mode & 0o777 == 0o600
    assert not [n for n in _names(tmp_path) if n.startswith(".rc-")]
    assert fileio.backup_paths(path)[2].read_text() == "0"


def test_cli_writes_through_a_link_and_says_so(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    from robocal.cli.main import main

    src = tmp_path / "src.json"
    src.write_text('{"j1": {"id": 1, "direction": 1, "homing_offset": 0.5}}\n')
    real = tmp_path / "robot"
    real.mkdir()
    (real / "cal.json").write_text('{"j1": {"id": 1, "direction": 1, "homing_offset": 0.25}}\n')
    link = tmp_path / "cal.json"
    link.symlink_to("robot/cal.json")
    assert main(["convert", str(src), str(link)]) == 0
    err = capsys.readouterr().err
    assert f"note: {link} is a symbolic link: wrote its target {real / 'cal.json'}" in err
    assert link.is_symlink()
    assert '"homing_offset": 0.5' in (real / "cal.json").read_text()
    assert '"homing_offset": 0.25' in (real / "cal.json.bak").read_text()
