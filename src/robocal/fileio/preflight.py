"""Output preflight: before any work is done, check that a file can be written where the user asked.

The folder exists and is writable (probed with a temporary file, which also catches read-only file systems),
the name and path are within the system's limits, the destination is not a directory nor write-protected, a
symbolic link is followed to the file it names, and the disk has room.
"""

from __future__ import annotations

import contextlib
import os
import tempfile
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path

from ..errors import FileWriteError
from ._paths import TMP_NAME_BYTES, TMP_SUFFIX, PathLike, encoded, name_max, parent_of, path_max, tmp_prefix

__all__ = ["OutputTarget", "check_not_an_input", "check_output_path", "preflight_output"]

_MAX_LINKS = 40  # like the kernel's ELOOP limit


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
        cur = link if link.is_absolute() else parent_of(cur) / link
    raise FileWriteError(f"{what} {p}: too many levels of symbolic links (a link loop?)")


def _check_lengths(p: Path, raw: bytes, what: str, folder: Path, shown: Path | None = None) -> None:
    """Refuse a name over the file system's limit (255 bytes) or a path over the system's (4095 bytes)."""
    shown = p if shown is None else shown
    name_limit = name_max(folder) if os.path.isdir(folder) else 255
    n = len(os.fsencode(p.name))
    if n > name_limit:
        raise FileWriteError(
            f"{what} {shown}: the file name is {n} bytes, longer than the file system's limit of {name_limit}"
        )
    path_limit = path_max(folder) if os.path.isdir(folder) else 4096
    longest = max(len(raw), len(os.fsencode(parent_of(p))) + 1 + TMP_NAME_BYTES)
    if longest >= path_limit:
        raise FileWriteError(
            f"{what} {shown}: the path is {longest} bytes, longer than the system's limit of {path_limit - 1}"
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
    raw = encoded(p, what)
    if not p.name or p.name in (".", ".."):
        raise FileWriteError(f"{what} {p}: expected a file name, not a folder")
    probe_folder = _nearest_existing(parent_of(p))
    _check_lengths(p, raw, what, probe_folder)
    try:
        target = _follow_link(p, what)
    except OSError as exc:
        raise FileWriteError(f"{what} {p}: cannot follow the symbolic link ({exc.strerror or exc})") from None
    via_link = target is not p
    folder = parent_of(target)
    if via_link:
        _check_lengths(target, encoded(target, what), what, _nearest_existing(folder), shown=p)
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
            fd, probe = tempfile.mkstemp(prefix=tmp_prefix(), suffix=TMP_SUFFIX, dir=folder)
        except OSError as exc:
            raise FileWriteError(f"{what} {p}: cannot write in {folder} ({reason(exc)})") from None
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
    path: PathLike,
    what: str = "output",
    *,
    size_hint: int = 0,
    create_dirs: bool = False,
    inputs: Mapping[str, PathLike | None] | None = None,
) -> Path:
    """Refuse, before any work is done, an output file that cannot be written (see :func:`preflight_output`).

    Args:
        path: The file that will be written.
        what: How the message names it (e.g. ``"--out"``).
        size_hint: Expected size of the new file, bytes (0 when unknown).
        create_dirs: Missing folders will be created by the writer.
        inputs: The command's inputs by how the message names them (``{"the dataset": root, "--urdf": urdf}``;
            ``None`` values are skipped): the output may be none of these files and lie in none of these folders
            (see :func:`check_not_an_input`).

    Returns:
        The path as given.

    Raises:
        FileWriteError: The folder is missing or not writable, the path is a directory, a name is too long,
            the disk is full, the path is an input or inside an input folder... (a ``UsageError``: exit 2,
            nothing written).
    """
    if inputs:
        check_not_an_input(path, what, inputs)
    return preflight_output(path, what, size_hint=size_hint, create_dirs=create_dirs).path


def check_not_an_input(path: PathLike, what: str, inputs: Mapping[str, PathLike | None]) -> None:
    """Refuse an output that would replace one of the command's inputs or write into an input folder.

    Paths are compared after symbolic links are followed (a link to the input is the input). Writing over an
    input keeps a ``.bak``, but the command would have read one file and left another: a report written over the
    calibration file it checked, a picture inside the dataset it read (the dataset is then another dataset).

    Args:
        path: The output file.
        what: How the message names it.
        inputs: Input files and folders by how the message names them (``None`` values are skipped).

    Raises:
        FileWriteError: Naming the output and the input (a ``UsageError``: exit 2).
    """
    out = Path(os.path.realpath(path))
    for name, given in inputs.items():
        if given is None:
            continue
        real = Path(os.path.realpath(given))
        if out == real:
            raise FileWriteError(f"{what} {path}: is {name} ({given}); give the output its own path")
        if real.is_dir() and real in out.parents:
            raise FileWriteError(
                f"{what} {path}: inside {name} ({given}); an output there changes the input: write it elsewhere"
            )


def reason(exc: OSError) -> str:
    """The OS's own words for ``exc`` (``"Read-only file system"``)."""
    return str(exc.strerror or exc)
