"""Safe file reading and atomic writing shared by every file format and workflow.

Writes go to a temporary file with a short name (``.rc-XXXXXXXX.tmp``) in the target's folder, are flushed and
fsynced, and the temporary file is renamed over the target, so a reader never sees half a file and a failure
leaves the old file untouched. The previous file is kept as a backup, made just as atomically: it is hard-linked
(or, where links are impossible, copied to a temporary file and fsynced) under a temporary name first, and only
then renamed into place, so a full disk never replaces a good backup with a truncated one.

Backups keep :data:`BACKUP_GENERATIONS` generations: ``NAME.bak`` (the newest), ``NAME.bak.1`` … ``NAME.bak.4``
(the oldest). Each write that changes the file shifts them by one and drops the oldest; a write of the same
bytes as the file already holds does not use a generation.

A destination that is a symbolic link is written through: the link stays a link, its target is replaced
atomically (the temporary file is made in the target's folder) and the backups are kept next to the target.
:func:`atomic_write` says so in its result, and a ``note`` is logged on the ``robocal.fileio`` logger (the CLI
prints it as a ``note:`` line).

:func:`check_output_path` (and :func:`preflight_output`, which returns the details) checks an output location
before any work is done: the folder exists and is writable, the name is not too long, the destination is not a
directory and the disk has room.

Every :class:`OSError` while writing becomes a :class:`~robocal.errors.FileWriteError` naming the path; every
one while reading a :class:`~robocal.errors.FileFormatError`.
"""

from __future__ import annotations

import contextlib
import hashlib
import logging
import os
import shutil
import tempfile
from dataclasses import dataclass
from pathlib import Path

from .errors import FileFormatError, FileWriteError

__all__ = [
    "BACKUP_GENERATIONS",
    "MAX_FILE_BYTES",
    "OutputTarget",
    "WriteResult",
    "atomic_write",
    "atomic_write_bytes",
    "atomic_write_text",
    "backup_path",
    "backup_paths",
    "check_output_path",
    "preflight_output",
    "read_bytes",
    "read_text",
]

log = logging.getLogger("robocal.fileio")

MAX_FILE_BYTES = 1024 * 1024 * 1024
"""Refuse to read calibration or description files larger than this (1 GiB: a URDF of a million joints is
about 300 MB, the largest file a robot can plausibly need)."""

BACKUP_GENERATIONS = 5
"""Backups kept per file: ``NAME.bak`` (newest), then ``NAME.bak.1`` … ``NAME.bak.4`` (oldest)."""

_TMP_PREFIX = ".rc-"
_TMP_SUFFIX = ".tmp"
_TMP_NAME_BYTES = len(_TMP_PREFIX) + 8 + len(_TMP_SUFFIX)  # mkstemp's random part is 8 characters
_MAX_LINKS = 40  # like the kernel's ELOOP limit


PathLike = str | os.PathLike[str]


def _current_umask() -> int:
    mask = os.umask(0o022)
    os.umask(mask)
    return mask


def _name_max(folder: Path) -> int:
    try:
        return int(os.pathconf(folder, "PC_NAME_MAX"))
    except (OSError, ValueError):
        return 255


def _path_max(folder: Path) -> int:
    try:
        return int(os.pathconf(folder, "PC_PATH_MAX"))
    except (OSError, ValueError):
        return 4096


def _encoded(p: Path, what: str) -> bytes:
    """The path's bytes as the OS sees them; refuses lone surrogates and NUL bytes."""
    try:
        raw = os.fsencode(p)
    except UnicodeError:
        raise FileWriteError(
            f"{what} {str(p)!a}: the name is not valid Unicode (a lone surrogate?) and cannot be a file name"
        ) from None
    if b"\x00" in raw:
        raise FileWriteError(f"{what} {str(p)!a}: a file name cannot contain a NUL byte")
    return raw


def _parent(p: Path) -> Path:
    return p.parent if str(p.parent) else Path(".")


def backup_paths(path: PathLike) -> tuple[Path, ...]:
    """Return every backup path of ``path``, newest first: ``NAME.bak``, ``NAME.bak.1`` … ``NAME.bak.4``.

    A name too long to take the longest suffix (``.bak.4``) within the file system's 255-byte name limit is
    shortened for its backups to its first bytes, ``~`` and 8 hex digits of its SHA-1, so every generation fits.
    """
    p = Path(path)
    suffixes = [".bak", *(f".bak.{i}" for i in range(1, BACKUP_GENERATIONS))]
    try:
        raw = os.fsencode(p.name)
    except UnicodeError:
        raw = p.name.encode("utf-8", "replace")
    limit = _name_max(_parent(p)) if _parent(p).is_dir() else 255
    stem = p.name
    if len(raw) + len(suffixes[-1]) > limit:
        digest = hashlib.sha1(raw).hexdigest()[:8]
        keep = limit - len(suffixes[-1]) - 1 - len(digest)
        stem = os.fsdecode(raw[:keep]) + "~" + digest
    return tuple(p.with_name(stem + s) for s in suffixes)


def backup_path(path: PathLike) -> Path:
    """Return the newest backup path ``NAME.bak`` used for ``path`` (see :func:`backup_paths`)."""
    return backup_paths(path)[0]


def read_bytes(path: PathLike, what: str = "file") -> bytes:
    """Read a whole file, turning OS errors into :class:`~robocal.errors.FileFormatError`.

    Args:
        path: File to read.
        what: Human name of the file's role, used in the error message (e.g. ``"URDF"``).

    Returns:
        The file's bytes.

    Raises:
        FileFormatError: The file is missing, unreadable, a directory, larger than 1 GiB, or its name is not
            a possible file name (a lone surrogate, a NUL byte, too long).
    """
    p = Path(path)
    try:
        size = p.stat().st_size
        if p.is_dir():
            raise FileFormatError(f"{what} {p}: is a directory, expected a file")
        if size > MAX_FILE_BYTES:
            raise FileFormatError(
                f"{what} {p}: {size} bytes is larger than robocal's {MAX_FILE_BYTES} byte input limit"
            )
        return p.read_bytes()
    except FileFormatError:  # a ValueError too: not to be taken for a bad file name below
        raise
    except FileNotFoundError:
        raise FileFormatError(f"{what} {p}: no such file") from None
    except PermissionError:
        raise FileFormatError(f"{what} {p}: permission denied") from None
    except OSError as exc:
        raise FileFormatError(f"{what} {p}: cannot read ({exc.strerror or exc})") from None
    except UnicodeError:
        raise FileFormatError(
            f"{what} {str(p)!a}: the name is not valid Unicode (a lone surrogate?)"
        ) from None
    except ValueError as exc:  # embedded NUL byte
        raise FileFormatError(f"{what} {str(p)!a}: not a possible file name ({exc})") from None


def read_text(path: PathLike, what: str = "file") -> str:
    """Read a UTF-8 text file; see :func:`read_bytes` for the errors raised."""
    data = read_bytes(path, what)
    try:
        return data.decode("utf-8-sig")
    except UnicodeDecodeError as exc:
        raise FileFormatError(f"{what} {path}: not UTF-8 text (byte {exc.start})") from None


@dataclass(frozen=True)
class OutputTarget:
    """Where a write to ``path`` will land, as found by :func:`preflight_output`.

    Attributes:
        path: The path as given.
        target: The file actually replaced: ``path`` itself, or the file a symbolic link ``path`` points to.
        via_link: ``path`` is a symbolic link (it stays one; ``target`` is replaced).
        exists: ``target`` exists now (it will be kept as a backup).
        free_bytes: Space available in the target's folder, bytes (None when the file system does not say).
    """

    path: Path
    target: Path
    via_link: bool
    exists: bool
    free_bytes: int | None


def _follow_link(p: Path, what: str) -> Path:
    """The file a (chain of) symbolic link(s) ``p`` ends at, made absolute; ``p`` when it is not a link."""
    cur = p
    for _ in range(_MAX_LINKS):
        if not os.path.islink(cur):
            return Path(os.path.abspath(cur)) if cur is not p else p
        link = Path(os.readlink(cur))
        cur = link if link.is_absolute() else _parent(cur) / link
    raise FileWriteError(f"{what} {p}: too many levels of symbolic links (a link loop?)")


def _check_lengths(p: Path, raw: bytes, what: str, folder: Path, shown: Path | None = None) -> None:
    """Refuse a name over the file system's limit (255 bytes) or a path over the system's (4095 bytes)."""
    shown = p if shown is None else shown
    name_max = _name_max(folder) if os.path.isdir(folder) else 255
    n = len(os.fsencode(p.name))
    if n > name_max:
        raise FileWriteError(
            f"{what} {shown}: the file name is {n} bytes, longer than the file system's limit of {name_max}"
        )
    path_max = _path_max(folder) if os.path.isdir(folder) else 4096
    longest = max(len(raw), len(os.fsencode(_parent(p))) + 1 + _TMP_NAME_BYTES)
    if longest >= path_max:
        raise FileWriteError(
            f"{what} {shown}: the path is {longest} bytes, longer than the system's limit of {path_max - 1}"
        )


def _free_bytes(folder: Path) -> int | None:
    try:
        st = os.statvfs(folder)
    except (OSError, AttributeError):
        return None
    blocks = st.f_bfree if hasattr(os, "geteuid") and os.geteuid() == 0 else st.f_bavail
    return int(blocks) * int(st.f_frsize)


def _nearest_existing(folder: Path) -> Path:
    for cand in (folder, *folder.parents):
        if os.path.lexists(cand):  # os.path swallows ENAMETOOLONG and friends
            return cand
    return Path(".")


def preflight_output(
    path: PathLike, what: str = "output", *, size_hint: int = 0, create_dirs: bool = False
) -> OutputTarget:
    """Check, before any work is done, that a file can be written at ``path``; nothing is left behind.

    Checks that the path is a possible file name (valid Unicode, no NUL byte, name within the file system's
    limit of usually 255 bytes, whole path within its limit of usually 4096 bytes), that the destination (or
    the file a symbolic link points to) is not a directory nor write-protected, that its folder exists (or,
    with ``create_dirs``, that the nearest existing parent is a folder) and is writable — by creating and
    removing a temporary file in it, which also catches read-only file systems — and that the disk has room
    for ``size_hint`` bytes plus one block.

    Args:
        path: The file that will be written.
        what: How the message names it (e.g. ``"--out"``).
        size_hint: Expected size of the new file, bytes (0 when unknown: one free block is then enough).
        create_dirs: Missing folders will be created by the writer; check the nearest existing one instead.

    Returns:
        The :class:`OutputTarget`.

    Raises:
        FileWriteError: A check failed; the message names the path and the reason (a ``UsageError``, exit 2).
    """
    p = Path(path)
    raw = _encoded(p, what)
    if not p.name or p.name in (".", ".."):
        raise FileWriteError(f"{what} {p}: expected a file name, not a folder")
    probe_folder = _nearest_existing(_parent(p))
    _check_lengths(p, raw, what, probe_folder)
    try:
        target = _follow_link(p, what)
    except OSError as exc:
        raise FileWriteError(f"{what} {p}: cannot follow the symbolic link ({exc.strerror or exc})") from None
    via_link = target is not p
    folder = _parent(target)
    if via_link:
        _check_lengths(target, _encoded(target, what), what, _nearest_existing(folder), shown=p)
    check_folder = folder
    if not os.path.isdir(folder):
        if os.path.lexists(folder):
            raise FileWriteError(f"{what} {p}: {folder} is not a folder")
        if not create_dirs:
            raise FileWriteError(f"{what} {p}: folder {folder} does not exist")
        check_folder = _nearest_existing(folder)
        if not os.path.isdir(check_folder):
            raise FileWriteError(f"{what} {p}: {check_folder} is not a folder")
    if os.path.isdir(target):
        link = f" (the link's target {target})" if via_link else ""
        raise FileWriteError(f"{what} {p}: it is a directory{link}")
    if check_folder == folder:  # a real probe: permissions, ACLs, read-only file systems, quotas on inodes
        try:
            fd, probe = tempfile.mkstemp(prefix=_TMP_PREFIX, suffix=_TMP_SUFFIX, dir=folder)
        except OSError as exc:
            raise FileWriteError(f"{what} {p}: cannot write in {folder} ({_reason(exc)})") from None
        os.close(fd)
        with contextlib.suppress(OSError):
            os.unlink(probe)
    elif not os.access(check_folder, os.W_OK | os.X_OK):
        raise FileWriteError(f"{what} {p}: cannot create folders in {check_folder} (permission denied)")
    exists = os.path.exists(target)
    if exists and not os.access(target, os.W_OK):
        raise FileWriteError(f"{what} {p}: the file is write-protected; make it writable to replace it")
    free = _free_bytes(check_folder)
    if free is not None:
        need = max(int(size_hint), 0) + 4096
        if free < need:
            raise FileWriteError(
                f"{what} {p}: only {free} bytes free in {check_folder}, {need} needed (disk full?)"
            )
    return OutputTarget(p, target, via_link, exists, free)


def check_output_path(
    path: PathLike, what: str = "output", *, size_hint: int = 0, create_dirs: bool = False
) -> Path:
    """Refuse, before any work is done, an output file that cannot be written (see :func:`preflight_output`).

    Args:
        path: The file that will be written.
        what: How the message names it (e.g. ``"--out"``).
        size_hint: Expected size of the new file, bytes (0 when unknown).
        create_dirs: Missing folders will be created by the writer.

    Returns:
        The path as given.

    Raises:
        FileWriteError: The folder is missing or not writable, the path is a directory, a name is too long,
            the disk is full... (a ``UsageError``: exit 2, nothing written).
    """
    return preflight_output(path, what, size_hint=size_hint, create_dirs=create_dirs).path


def _reason(exc: OSError) -> str:
    return str(exc.strerror or exc)


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
    fd, tmp = tempfile.mkstemp(prefix=_TMP_PREFIX, suffix=_TMP_SUFFIX, dir=folder)
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

    The new contents go to ``.rc-XXXXXXXX.tmp`` in the target's folder and are fsynced; the current file is
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
    folder = _parent(target)
    tmp_name: str | None = None
    staged: str | None = None
    made_backup: Path | None = None
    rotated = False
    try:
        fd, tmp_name = tempfile.mkstemp(prefix=_TMP_PREFIX, suffix=_TMP_SUFFIX, dir=folder)
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
        tmp_name = None
    except BaseException as exc:
        for leftover in (tmp_name, staged):
            if leftover is not None:
                with contextlib.suppress(OSError):
                    os.unlink(leftover)
        if isinstance(exc, OSError):
            state = "the file is unchanged" if rotated else "the file and its backups are unchanged"
            raise FileWriteError(f"cannot write {p}: {_reason(exc)}; {state}") from None
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
