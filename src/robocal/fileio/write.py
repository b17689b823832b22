"""Atomic writes with rotating backups (see :mod:`robocal.fileio`)."""

from __future__ import annotations

import contextlib
import logging
import os
import re
import shutil
import stat
import tempfile
from dataclasses import dataclass
from pathlib import Path

from ..errors import FileWriteError
from ._paths import TMP_PREFIX, TMP_SUFFIX, PathLike, backup_paths, parent_of, tmp_prefix
from .preflight import preflight_output, reason

__all__ = [
    "WriteResult",
    "atomic_write",
    "atomic_write_bytes",
    "atomic_write_text",
    "files_written",
    "process_gone",
    "remove_stale_temporaries",
]

log = logging.getLogger("robocal.fileio")

_STALE_NAME = re.compile(re.escape(TMP_PREFIX) + r"([1-9][0-9]{0,9})-[A-Za-z0-9_]{8}" + re.escape(TMP_SUFFIX))
_written: list[Path] = []


def files_written() -> tuple[Path, ...]:
    """Every path :func:`atomic_write` completed in this process, in order (what an interruption leaves)."""
    return tuple(_written)


def process_gone(pid: int) -> bool:
    """True only when no process ``pid`` exists (a process of another user, or one we cannot ask, counts)."""
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return True
    except OSError:  # EPERM: it exists, owned by someone else
        return False
    return False


def remove_stale_temporaries(folder: Path) -> list[Path]:
    """Remove the temporary files a killed robocal process left in ``folder``; returns what was removed.

    A temporary file is named ``.rc-<pid>-XXXXXXXX.tmp``. One is removed only when it is a regular file (not a
    link), owned by this user, not this process's, and no process ``pid`` exists any more; anything else
    (another user's file, a live writer, a name of another shape) is left alone. Errors are ignored: this is
    housekeeping before a write, never a reason for the write to fail.

    Args:
        folder: The folder a file is about to be written in.
    """
    removed: list[Path] = []
    me = os.getpid()
    try:
        with os.scandir(folder) as entries:
            names = [e.name for e in entries if e.name.startswith(TMP_PREFIX) and e.name.endswith(TMP_SUFFIX)]
    except OSError:
        return removed
    for name in names:
        match = _STALE_NAME.fullmatch(name)
        if match is None or int(match.group(1)) == me:
            continue
        path = folder / name
        try:
            st = os.lstat(path)
            if not stat.S_ISREG(st.st_mode) or st.st_uid != os.geteuid():
                continue
            if process_gone(int(match.group(1))):
                os.unlink(path)
                removed.append(path)
        except OSError:
            continue
    return removed


def _current_umask() -> int:
    mask = os.umask(0o022)
    os.umask(mask)
    return mask


@dataclass(frozen=True)
class WriteResult:
    """What :func:`atomic_write` did.

    Attributes:
        path: The path as given.
        target: The file replaced (the link's target when ``path`` is a symbolic link).
        via_link: ``path`` is a symbolic link; it was kept and its target written.
        backup: Where the previous contents were kept (None: there was no previous file, ``backup=False``, or
            the bytes did not change).
    """

    path: Path
    target: Path
    via_link: bool
    backup: Path | None

    def describe(self) -> str:
        """One sentence for a person, e.g. ``"cal.yaml is a symbolic link: wrote its target /x/cal.yaml"``."""
        text = f"wrote {self.path}"
        if self.via_link:
            text = f"{self.path} is a symbolic link: wrote its target {self.target}"
        if self.backup is not None:
            text += f" (previous version kept as {self.backup})"
        return text


def _fsync_dir(folder: Path) -> None:
    with contextlib.suppress(OSError):  # make the renames durable where the OS allows it
        dir_fd = os.open(folder, os.O_RDONLY)
        try:
            os.fsync(dir_fd)
        finally:
            os.close(dir_fd)


def _same_bytes(path: Path, data: bytes) -> bool:
    try:
        if path.stat().st_size != len(data):
            return False
        return path.read_bytes() == data
    except OSError:
        return False


def _stage_backup(target: Path, folder: Path) -> str:
    """A temporary name in ``folder`` holding the current contents of ``target``, complete and durable."""
    fd, tmp = tempfile.mkstemp(prefix=tmp_prefix(), suffix=TMP_SUFFIX, dir=folder)
    os.close(fd)
    os.unlink(tmp)
    try:
        os.link(target, tmp, follow_symlinks=False)  # no data copied: a full disk cannot truncate it
        return tmp
    except OSError:
        pass
    fd = os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o600)
    try:
        with os.fdopen(fd, "wb") as dst, open(target, "rb") as src:
            shutil.copyfileobj(src, dst)
            dst.flush()
            os.fsync(dst.fileno())
        shutil.copystat(target, tmp)
    except BaseException:
        with contextlib.suppress(OSError):
            os.unlink(tmp)
        raise
    return tmp


def _rotate_and_place(staged: str, target: Path) -> Path:
    """Shift ``NAME.bak`` … ``NAME.bak.3`` one generation older (dropping the oldest) and put ``staged`` first."""
    gens = backup_paths(target)
    for older, newer in zip(reversed(gens[1:]), reversed(gens[:-1]), strict=True):
        if newer.exists() or newer.is_symlink():
            os.replace(newer, older)
    os.replace(staged, gens[0])
    return gens[0]


def atomic_write(path: PathLike, data: bytes, *, backup: bool = True) -> WriteResult:
    """Write ``data`` to ``path`` atomically, keeping earlier versions as rotating backups.

    Temporary files a killed robocal left in the folder are removed first (:func:`remove_stale_temporaries`).
    The new contents go to ``.rc-<pid>-XXXXXXXX.tmp`` in the target's folder and are fsynced; the current file is
    hard-linked (or copied and fsynced) to another temporary name; only when both are complete are the backups
    rotated (``NAME.bak`` → ``NAME.bak.1`` …, :data:`BACKUP_GENERATIONS` kept) and the files renamed into
    place. A symbolic link is written through (see the module docstring). The file keeps its permission bits
    (and owner, where allowed); a new file gets ``0666 & ~umask``.

    Args:
        path: Destination file. Its folder must exist.
        data: Complete new contents.
        backup: Keep the previous file as a backup generation.

    Returns:
        The :class:`WriteResult`.

    Raises:
        FileWriteError: The folder does not exist or is not writable, the disk is full, the file system is
            read-only, a name is too long, or the destination is a directory. Nothing is changed then: the
            file and every backup are as before, and no temporary file is left.
    """
    plan = preflight_output(path, "cannot write", size_hint=len(data))
    p, target = plan.path, plan.target
    folder = parent_of(target)
    tmp_name: str | None = None
    staged: str | None = None
    made_backup: Path | None = None
    rotated = False
    remove_stale_temporaries(folder)
    try:
        fd, tmp_name = tempfile.mkstemp(prefix=tmp_prefix(), suffix=TMP_SUFFIX, dir=folder)
        with os.fdopen(fd, "wb") as fh:
            fh.write(data)
            fh.flush()
            os.fsync(fh.fileno())
        if target.exists():
            st = target.stat()
            with contextlib.suppress(OSError):
                os.chmod(tmp_name, st.st_mode & 0o7777)
            if hasattr(os, "chown") and (st.st_uid, st.st_gid) != (os.geteuid(), os.getegid()):
                with contextlib.suppress(OSError):
                    os.chown(tmp_name, st.st_uid, st.st_gid)
            if backup and not _same_bytes(target, data):
                staged = _stage_backup(target, folder)
        else:  # mkstemp creates 0600; a new file gets the usual 0666 & ~umask
            with contextlib.suppress(OSError):
                os.chmod(tmp_name, 0o666 & ~_current_umask())
        if staged is not None:
            rotated = True
            made_backup = _rotate_and_place(staged, target)
            staged = None
        os.replace(tmp_name, target)
        _written.append(p)  # at once: an interruption from here on must say this file was written
        tmp_name = None
    except BaseException as exc:
        for leftover in (tmp_name, staged):
            if leftover is not None:
                with contextlib.suppress(OSError):
                    os.unlink(leftover)
        if isinstance(exc, OSError):
            state = "the file is unchanged" if rotated else "the file and its backups are unchanged"
            raise FileWriteError(f"cannot write {p}: {reason(exc)}; {state}") from None
        raise
    _fsync_dir(folder)
    result = WriteResult(p, target, plan.via_link, made_backup)
    if plan.via_link:
        log.info("%s", result.describe())
    return result


def atomic_write_bytes(path: PathLike, data: bytes, *, backup: bool = True) -> Path:
    """Write ``data`` to ``path`` atomically with rotating backups; see :func:`atomic_write`.

    Returns:
        The destination path as given (a symbolic link stays one; its target was written).

    Raises:
        FileWriteError: See :func:`atomic_write`; nothing is changed then.
    """
    return atomic_write(path, data, backup=backup).path


def atomic_write_text(path: PathLike, text: str, *, backup: bool = True) -> Path:
    """Write UTF-8 ``text`` atomically; see :func:`atomic_write`.

    Raises:
        FileWriteError: See :func:`atomic_write`, or ``text`` holds a lone surrogate (it cannot be UTF-8).
    """
    try:
        data = text.encode("utf-8")
    except UnicodeEncodeError as exc:
        bad = text[exc.start : exc.end]
        line = text.count("\n", 0, exc.start) + 1
        raise FileWriteError(
            f"cannot write {path}: line {line} holds {bad!a}, a lone surrogate that is not valid Unicode; "
            "nothing written"
        ) from None
    return atomic_write_bytes(path, data, backup=backup)
