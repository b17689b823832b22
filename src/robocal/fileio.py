"""Safe file reading and atomic writing shared by every file format and workflow.

Writes go to a temporary file in the target's folder, are flushed and fsynced, the previous file is kept as
``NAME.bak`` and the temporary file is renamed over the target, so a reader never sees half a file and a
failure leaves the old file untouched.
"""

from __future__ import annotations

import contextlib
import os
import shutil
import tempfile
from pathlib import Path

from .errors import FileFormatError, UsageError

__all__ = ["atomic_write_bytes", "atomic_write_text", "backup_path", "check_output_path", "read_bytes", "read_text"]

MAX_FILE_BYTES = 256 * 1024 * 1024
"""Refuse to read calibration or description files larger than this (256 MiB)."""


def _current_umask() -> int:
    mask = os.umask(0o022)
    os.umask(mask)
    return mask


def backup_path(path: str | os.PathLike[str]) -> Path:
    """Return the backup path ``NAME.bak`` used for ``path``."""
    p = Path(path)
    return p.with_name(p.name + ".bak")


def read_bytes(path: str | os.PathLike[str], what: str = "file") -> bytes:
    """Read a whole file, turning OS errors into :class:`~robocal.errors.FileFormatError`.

    Args:
        path: File to read.
        what: Human name of the file's role, used in the error message (e.g. ``"URDF"``).

    Returns:
        The file's bytes.

    Raises:
        FileFormatError: The file is missing, unreadable, a directory or larger than 256 MiB.
    """
    p = Path(path)
    try:
        size = p.stat().st_size
        if p.is_dir():
            raise FileFormatError(f"{what} {p}: is a directory, expected a file")
        if size > MAX_FILE_BYTES:
            raise FileFormatError(f"{what} {p}: {size} bytes is larger than the {MAX_FILE_BYTES} byte limit")
        return p.read_bytes()
    except FileNotFoundError:
        raise FileFormatError(f"{what} {p}: no such file") from None
    except PermissionError:
        raise FileFormatError(f"{what} {p}: permission denied") from None
    except OSError as exc:
        raise FileFormatError(f"{what} {p}: cannot read ({exc.strerror or exc})") from None


def read_text(path: str | os.PathLike[str], what: str = "file") -> str:
    """Read a UTF-8 text file; see :func:`read_bytes` for the errors raised."""
    data = read_bytes(path, what)
    try:
        return data.decode("utf-8-sig")
    except UnicodeDecodeError as exc:
        raise FileFormatError(f"{what} {path}: not UTF-8 text (byte {exc.start})") from None


def check_output_path(path: str | os.PathLike[str], what: str = "output") -> Path:
    """Refuse an output path whose folder does not exist or that is a directory, before any work is done.

    Args:
        path: The file that will be written.
        what: How the message names it (e.g. ``"--out"``).

    Returns:
        The path (its parent is ``.`` when it has none).

    Raises:
        UsageError: The folder is missing, or the path is a directory.
    """
    p = Path(path)
    parent = p.parent if str(p.parent) else Path(".")
    if not parent.is_dir():
        raise UsageError(f"{what} {p}: folder {parent} does not exist")
    if p.is_dir():
        raise UsageError(f"{what} {p}: it is a directory")
    return p


def atomic_write_bytes(path: str | os.PathLike[str], data: bytes, *, backup: bool = True) -> Path:
    """Write ``data`` to ``path`` atomically, keeping the previous file as ``NAME.bak``.

    Args:
        path: Destination file. Its folder must exist.
        data: Complete new contents.
        backup: Copy an existing file to ``NAME.bak`` before replacing it.

    Returns:
        The destination path.

    Raises:
        UsageError: The folder does not exist, is not writable, the disk is full, or the destination is a
            directory. Nothing is changed then.
    """
    p = check_output_path(path, "cannot write")
    parent = p.parent
    try:
        fd, tmp_name = tempfile.mkstemp(prefix=f".{p.name}.", suffix=".tmp", dir=parent)
    except OSError as exc:
        raise UsageError(f"cannot write {p}: {exc.strerror or exc}") from None
    try:
        with os.fdopen(fd, "wb") as fh:
            fh.write(data)
            fh.flush()
            os.fsync(fh.fileno())
        if p.exists():
            with contextlib.suppress(OSError):
                os.chmod(tmp_name, p.stat().st_mode & 0o7777)
            if backup:
                shutil.copy2(p, backup_path(p))
        else:  # mkstemp creates 0600; a new file gets the usual 0666 & ~umask
            with contextlib.suppress(OSError):
                os.chmod(tmp_name, 0o666 & ~_current_umask())
        os.replace(tmp_name, p)
    except BaseException as exc:
        with contextlib.suppress(OSError):
            os.unlink(tmp_name)
        if isinstance(exc, OSError):
            raise UsageError(f"cannot write {p}: {exc.strerror or exc}") from None
        raise
    with contextlib.suppress(OSError):  # make the rename durable where the OS allows it
        dir_fd = os.open(parent, os.O_RDONLY)
        try:
            os.fsync(dir_fd)
        finally:
            os.close(dir_fd)
    return p


def atomic_write_text(path: str | os.PathLike[str], text: str, *, backup: bool = True) -> Path:
    """Write UTF-8 ``text`` atomically; see :func:`atomic_write_bytes`."""
    return atomic_write_bytes(path, text.encode("utf-8"), backup=backup)
