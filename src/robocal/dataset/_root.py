"""A new dataset root, built in a temporary folder beside the destination and renamed into place.

:func:`check_destination` refuses a destination before anything is written; :func:`make_temp_root` makes the
hidden sibling ``.DST.robocal-*`` (same file system, so the final rename is atomic); :func:`prepare_root` carries
every file that is not re-calibrated into it (videos hard-linked, copied where linking fails; symbolic links
followed); :func:`publish_root` renames it to ``DST``, replacing an existing ``DST`` only then.
"""

from __future__ import annotations

import os
import re
import shutil
import tempfile
from pathlib import Path

from ..errors import FileFormatError, FileWriteError, UsageError
from ..fileio import process_gone
from ._layout import DatasetLayout

__all__ = ["check_destination", "make_temp_root", "prepare_root", "publish_root", "sweep_leftovers"]

_VIDEO_SUFFIXES = (".mp4", ".mkv", ".avi")


def check_destination(src: Path, dst: Path, overwrite: bool) -> None:
    """Refuse a destination that exists (without ``overwrite``), overlaps the source or has no parent.

    Raises:
        UsageError: Naming the problem.
    """
    s, d = src.resolve(), dst.resolve()
    if s == d or s in d.parents or d in s.parents:
        raise UsageError(f"destination {dst} overlaps the source {src}; choose a separate folder")
    if dst.exists() and not overwrite:
        raise UsageError(f"destination {dst} already exists; pass --overwrite to replace it")
    if dst.exists() and not dst.is_dir():
        raise UsageError(f"destination {dst} exists and is not a folder")
    if dst.is_symlink() and not dst.exists():
        raise UsageError(f"destination {dst} is a broken symbolic link; remove it or choose another folder")
    if not dst.parent.is_dir():
        raise UsageError(f"destination {dst}: parent folder {dst.parent} does not exist")


def _carry(src: Path, dst: Path, link: bool) -> None:
    """Hard-link (``link``, copy where the file system cannot) or copy the file ``src`` is or points to."""
    real = Path(os.path.realpath(src))  # a relative symbolic link would break in another folder
    dst.parent.mkdir(parents=True, exist_ok=True)
    if link:
        try:
            os.link(real, dst)
            return
        except OSError:
            pass
    shutil.copy2(real, dst)


def _source_files(root: Path) -> list[tuple[str, Path]]:
    """Every file under ``root`` as (relative POSIX path, path), following symbolic links to folders.

    Raises:
        FileFormatError: A broken symbolic link (naming it).
    """
    out: list[tuple[str, Path]] = []
    seen: set[str] = set()
    for dirpath, dirnames, filenames in os.walk(root, followlinks=True):
        real = os.path.realpath(dirpath)
        if real in seen:  # a link loop
            dirnames.clear()
            continue
        seen.add(real)
        for name in filenames:
            path = Path(dirpath) / name
            rel = path.relative_to(root).as_posix()
            if not path.exists():
                raise FileFormatError(f"dataset {root}: {rel} is a broken symbolic link")
            out.append((rel, path))
    return sorted(out)


def prepare_root(layout: DatasetLayout, tmp: Path) -> None:
    """Carry every file that is not re-calibrated into ``tmp`` (videos linked) and create the data folders.

    Symbolic links (to files or folders) are followed: the new root holds the files themselves.

    Raises:
        FileFormatError: A broken symbolic link or a file that cannot be read or written.
    """
    root = layout.root
    special = set(layout.data_files) | set(layout.episode_files) | {"meta/stats.json"}
    try:
        for rel, path in _source_files(root):
            if rel not in special:
                _carry(path, tmp / rel, link=rel.startswith("videos/") or path.suffix in _VIDEO_SUFFIXES)
        for rel in layout.data_files:
            (tmp / rel).parent.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise FileFormatError(f"dataset {root}: cannot copy {exc.filename or ''} ({exc.strerror})") from None


def _prefixes(final: Path, kind: str) -> tuple[str, str]:
    """The two name prefixes of a temporary folder of ``kind`` beside ``final``: its own, and the one for long names."""
    return f".{final.name}.{kind}-", f".rc-{kind}-"


def make_temp_root(dst: Path, kind: str = "robocal", *, owned: bool = False) -> Path:
    """Create an empty temporary folder beside ``dst`` (same file system, so the final rename is atomic).

    ``owned``: the name carries this process's id (``.DST.robocal-<pid>-xxxxxxxx``), so a later run can tell a
    folder left by a run that was killed (:func:`sweep_leftovers`) from one still being written.
    """
    final = Path(os.path.abspath(dst))  # "." or "out/.." have no usable name or parent otherwise
    own, short = _prefixes(final, kind)
    prefix = own if len(os.fsencode(own)) + 20 <= 255 else short  # a long DST name: a short name still fits
    if owned:
        prefix += f"{os.getpid()}-"
    try:
        return Path(tempfile.mkdtemp(prefix=prefix, dir=final.parent))
    except OSError as exc:
        raise FileWriteError(
            f"cannot write {dst}: cannot create a folder in {final.parent} ({exc.strerror or exc}); nothing written"
        ) from None
    except UnicodeError:
        raise FileWriteError(
            f"cannot write {str(dst)!a}: the name is not valid Unicode (a lone surrogate)"
        ) from None


def publish_root(tmp: Path, dst: Path) -> None:
    """Rename the finished ``tmp`` root to ``dst``, replacing an existing ``dst`` only now.

    Raises:
        FileFormatError: The rename failed; an existing ``dst`` is put back.
    """
    final = Path(os.path.abspath(dst))
    try:
        if not final.exists():
            os.replace(tmp, final)
            return
        old_dir = make_temp_root(final, "old", owned=True)
        os.replace(final, old_dir / "root")
        try:
            os.replace(tmp, final)
        except OSError:
            os.replace(old_dir / "root", final)
            os.rmdir(old_dir)
            raise
        shutil.rmtree(old_dir, ignore_errors=True)
    except OSError as exc:
        raise FileFormatError(
            f"destination {dst}: cannot move the new dataset into place ({exc.strerror})"
        ) from None


def sweep_leftovers(dst: Path) -> tuple[list[str], list[str]]:
    """Remove the temporary folders beside ``dst`` that runs killed midway left behind; name the others.

    A folder ``.DST.robocal-<pid>-*`` whose process no longer runs is removed (it only ever held a partial new
    root). A ``.DST.old-<pid>-*`` folder of a dead run holds the previous ``DST`` if the run was killed between
    its two renames: it is removed when ``DST`` exists (the new root was in place), else kept and named. Folders
    without a process id (older robocal versions, the datatrove adapter) or of a process still running are named.

    Returns:
        (notes on what was removed, warnings naming what was kept).
    """
    final = Path(os.path.abspath(dst))
    notes: list[str] = []
    warnings: list[str] = []
    try:
        entries = sorted(os.listdir(final.parent))
    except OSError:
        return notes, warnings
    for kind in ("robocal", "old"):
        for prefix in _prefixes(final, kind):
            pattern = re.compile(re.escape(prefix) + r"(?:(\d+)-)?[a-z0-9_]{8}\Z")
            for name in entries:
                m = pattern.match(name)
                path = final.parent / name
                if m is None or not path.is_dir() or path.is_symlink():
                    continue
                pid = int(m.group(1)) if m.group(1) else None
                if pid is None or not process_gone(pid):
                    who = "an unknown run" if pid is None else f"process {pid}, which is still running"
                    warnings.append(f"{path} was left by {who}; remove it if no robocal run is writing {dst}")
                elif kind == "old" and (path / "root").exists() and not final.exists():
                    warnings.append(
                        f"{path / 'root'} holds {dst} as it was before a run (process {pid}) was killed while "
                        f"replacing it; move it back to {dst} or remove it"
                    )
                else:
                    shutil.rmtree(path, ignore_errors=True)
                    if not path.exists():
                        notes.append(f"removed {path}, left by a run that was killed (process {pid})")
    return notes, warnings
