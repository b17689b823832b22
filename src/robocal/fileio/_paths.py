"""Path helpers shared by reading, preflight and writing: limits, encodings, temporary and backup names."""

from __future__ import annotations

import hashlib
import os
from pathlib import Path

from ..errors import FileWriteError

BACKUP_GENERATIONS = 5
"""Backups kept per file: ``NAME.bak`` (newest), then ``NAME.bak.1`` … ``NAME.bak.4`` (oldest)."""

TMP_PREFIX = ".rc-"
TMP_SUFFIX = ".tmp"
TMP_PID_DIGITS = 10  # a pid is at most 2**31 - 1
TMP_NAME_BYTES = len(TMP_PREFIX) + TMP_PID_DIGITS + 1 + 8 + len(TMP_SUFFIX)  # mkstemp's random part: 8 chars


def tmp_prefix() -> str:
    """The prefix of this process's temporary files: ``.rc-<pid>-`` (a later run removes them if it died)."""
    return f"{TMP_PREFIX}{os.getpid()}-"

PathLike = str | os.PathLike[str]


def name_max(folder: Path) -> int:
    """The file system's longest file name in ``folder``, bytes (255 when it does not say)."""
    try:
        return int(os.pathconf(folder, "PC_NAME_MAX"))
    except (OSError, ValueError):
        return 255


def path_max(folder: Path) -> int:
    """The system's longest path in ``folder``, bytes (4096 when it does not say)."""
    try:
        return int(os.pathconf(folder, "PC_PATH_MAX"))
    except (OSError, ValueError):
        return 4096


def encoded(p: Path, what: str) -> bytes:
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


def parent_of(p: Path) -> Path:
    """The folder of ``p`` (``.`` for a bare name)."""
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
    limit = name_max(parent_of(p)) if parent_of(p).is_dir() else 255
    stem = p.name
    if len(raw) + len(suffixes[-1]) > limit:
        digest = hashlib.sha1(raw).hexdigest()[:8]
        keep = limit - len(suffixes[-1]) - 1 - len(digest)
        stem = os.fsdecode(raw[:keep]) + "~" + digest
    return tuple(p.with_name(stem + s) for s in suffixes)


def backup_path(path: PathLike) -> Path:
    """Return the newest backup path ``NAME.bak`` used for ``path`` (see :func:`backup_paths`)."""
    return backup_paths(path)[0]
