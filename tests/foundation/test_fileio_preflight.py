"""``robocal.fileio.check_output_path`` / ``preflight_output``: an output location is checked before any work.

The read-only and full-disk cases run on a real tmpfs mounted in a private user+mount namespace
(``unshare -rm``), so the kernel itself says EROFS / ENOSPC; they are skipped where namespaces are not allowed.
"""

from __future__ import annotations

import os
from pathlib import Path

import pytest
from fs_sandbox import FILL_DISK, needs_unshare, needs_user_ns, run_on_tmpfs, run_without_privileges

from robocal.errors import FileWriteError, UsageError
from robocal.fileio import atomic_write_text, check_output_path, preflight_output


def test_signature_stays_compatible_and_returns_the_path(tmp_path: Path) -> None:
    assert check_output_path(tmp_path / "cal.yaml") == tmp_path / "cal.yaml"
    assert check_output_path(str(tmp_path / "cal.yaml"), "--out") == tmp_path / "cal.yaml"
    with pytest.raises(UsageError, match=r"^--out .*: folder .* does not exist$"):
        check_output_path(tmp_path / "no" / "cal.yaml", "--out")
    # create_dirs: the nearest existing folder is checked instead
    assert (
        check_output_path(tmp_path / "a" / "b" / "cal.json", create_dirs=True)
        == tmp_path / "a" / "b" / "cal.json"
    )
    assert not (tmp_path / "a").exists()
    assert sorted(p.name for p in tmp_path.iterdir()) == []  # the probe file is gone


def test_directory_and_file_in_the_way(tmp_path: Path) -> None:
    with pytest.raises(FileWriteError, match="it is a directory"):
        check_output_path(tmp_path, "--out")
    (tmp_path / "plain").write_text("x")
    with pytest.raises(FileWriteError, match=r"plain is not a folder"):
        check_output_path(tmp_path / "plain" / "cal.yaml", "--out")
    with pytest.raises(FileWriteError, match=r"plain is not a folder"):
        check_output_path(tmp_path / "plain" / "sub" / "cal.yaml", "--out", create_dirs=True)


def test_name_and_path_limits(tmp_path: Path) -> None:
    ok = tmp_path / ("n" * 255)
    assert check_output_path(ok) == ok
    too_long = tmp_path / ("n" * 256)
    with pytest.raises(
        FileWriteError, match=r"file name is 256 bytes, longer than the file system's limit of 255"
    ):
        check_output_path(too_long, "--out")
    multibyte = tmp_path / ("é" * 128)  # 256 bytes in UTF-8
    with pytest.raises(FileWriteError, match="256 bytes"):
        check_output_path(multibyte)
    deep = tmp_path.joinpath(*(["d" * 200] * 21), "cal.yaml")  # > 4096 bytes
    with pytest.raises(
        FileWriteError, match=r"the path is \d+ bytes, longer than the system's limit of 4095"
    ):
        check_output_path(deep, "--out")
    with pytest.raises(FileWriteError, match=r"lone surrogate"):
        check_output_path(tmp_path / "bad\udcff\ud800.yaml", "--out")
    with pytest.raises(FileWriteError, match="NUL byte"):
        check_output_path(tmp_path / "a\x00b", "--out")


def test_names_of_245_to_255_bytes_can_be_written(tmp_path: Path) -> None:
    """The temporary file has a short name of its own, so the longest names ``cp`` can write work too."""
    for n in (245, 250, 255):
        p = tmp_path / ("c" * n)
        atomic_write_text(p, "one\n")
        atomic_write_text(p, "two\n")
        assert p.read_text() == "two\n"
    names = sorted(p.name for p in tmp_path.iterdir())
    assert not [n for n in names if n.endswith(".tmp")]
    assert len(names) == 6  # three files, one backup each


def test_symlink_preflight_names_the_target(tmp_path: Path) -> None:
    real_dir = tmp_path / "real"
    real_dir.mkdir()
    (real_dir / "cal.yaml").write_text("x")
    link = tmp_path / "cal.yaml"
    link.symlink_to(Path("real") / "cal.yaml")
    plan = preflight_output(link)
    assert plan.via_link and plan.exists
    assert plan.target == real_dir / "cal.yaml"
    (tmp_path / "loop").symlink_to("loop")
    with pytest.raises(FileWriteError, match="too many levels of symbolic links"):
        check_output_path(tmp_path / "loop", "--out")
    (tmp_path / "to_dir").symlink_to("real")
    with pytest.raises(FileWriteError, match="it is a directory"):
        check_output_path(tmp_path / "to_dir")


@pytest.mark.skipif(os.geteuid() == 0, reason="root may write anywhere")
def test_write_protected_file_and_folder(tmp_path: Path) -> None:
    f = tmp_path / "cal.yaml"
    f.write_text("x")
    f.chmod(0o444)
    with pytest.raises(FileWriteError, match="write-protected"):
        check_output_path(f, "--out")
    f.chmod(0o644)
    tmp_path.chmod(0o500)
    try:
        with pytest.raises(FileWriteError, match="cannot write in"):
            check_output_path(f, "--out")
    finally:
        tmp_path.chmod(0o700)


@needs_unshare
def test_read_only_file_system_is_refused_before_any_work(tmp_path: Path) -> None:
    out = run_on_tmpfs(
        tmp_path,
        "(mnt / 'cal.yaml').write_text('old')\n",
        """
        from robocal.errors import FileWriteError
        from robocal.fileio import check_output_path, atomic_write_text
        res = {}
        for name, fn in (("check", lambda: check_output_path(mnt / "cal.yaml", "--out")),
                         ("write", lambda: atomic_write_text(mnt / "cal.yaml", "new"))):
            try:
                fn()
                res[name] = "passed"
            except FileWriteError as exc:
                res[name] = str(exc)
        res["content"] = (mnt / "cal.yaml").read_text()
        print(json.dumps(res))
        """,
        read_only=True,
    )
    assert out["check"].startswith("--out ") and "Read-only file system" in out["check"]
    assert "cal.yaml" in out["write"] and "Read-only file system" in out["write"]
    assert out["content"] == "old"


@needs_unshare
def test_full_disk_is_refused_before_any_work(tmp_path: Path) -> None:
    out = run_on_tmpfs(
        tmp_path,
        FILL_DISK,
        """
        from robocal.errors import FileWriteError
        from robocal.fileio import check_output_path
        try:
            check_output_path(mnt / "cal.yaml", "--out")
            print(json.dumps({"msg": "passed"}))
        except FileWriteError as exc:
            print(json.dumps({"msg": str(exc), "files": sorted(os.listdir(mnt))}))
        """,
    )
    assert out["msg"].startswith("--out ") and "disk full" in out["msg"]
    assert out["files"] == ["fill"]


@needs_user_ns
def test_permissions_as_an_ordinary_user(tmp_path: Path) -> None:
    """Root passes every permission check; a user namespace takes that away, so the checks are real."""
    (tmp_path / "ro").mkdir()
    (tmp_path / "ro" / "cal.yaml").write_text("old")
    (tmp_path / "ro").chmod(0o500)
    (tmp_path / "rw").mkdir()
    (tmp_path / "rw" / "locked.yaml").write_text("keep")
    (tmp_path / "rw" / "locked.yaml").chmod(0o444)
    try:
        out = run_without_privileges(
            """
            from robocal.errors import FileWriteError
            from robocal.fileio import atomic_write_text, check_output_path
            res = {}
            for key, fn in (
                ("folder", lambda: check_output_path(Path(argv[0]) / "ro" / "cal.yaml", "--out")),
                ("write", lambda: atomic_write_text(Path(argv[0]) / "ro" / "cal.yaml", "new")),
                ("locked", lambda: check_output_path(Path(argv[0]) / "rw" / "locked.yaml", "--out")),
                ("ok", lambda: check_output_path(Path(argv[0]) / "rw" / "new.yaml", "--out")),
            ):
                try:
                    res[key] = str(fn())
                except FileWriteError as exc:
                    res[key] = "error: " + str(exc)
            print(json.dumps(res))
            """,
            str(tmp_path),
        )
    finally:
        (tmp_path / "ro").chmod(0o700)
    assert (
        out["folder"]
        == f"error: --out {tmp_path}/ro/cal.yaml: cannot write in {tmp_path}/ro (Permission denied)"
    )
    assert (
        out["write"].startswith(f"error: cannot write {tmp_path}/ro/cal.yaml: ")
        and "Permission denied" in out["write"]
    )
    assert out["locked"] == (
        f"error: --out {tmp_path}/rw/locked.yaml: the file is write-protected; make it writable to replace it"
    )
    assert out["ok"] == f"{tmp_path}/rw/new.yaml"
    assert (tmp_path / "ro" / "cal.yaml").read_text() == "old"
    assert sorted(p.name for p in (tmp_path / "rw").iterdir()) == ["locked.yaml"]
