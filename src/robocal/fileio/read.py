"""Bounded reads: a whole file, or UTF-8 text, with every OS error a :class:`~robocal.errors.FileFormatError`."""

from __future__ import annotations

from pathlib import Path
from typing import BinaryIO

from ..errors import FileFormatError
from ._paths import PathLike

__all__ = ["MAX_DOCUMENT_BYTES", "MAX_FILE_BYTES", "MAX_URDF_BYTES", "read_bytes", "read_text"]

MAX_FILE_BYTES = 1024 * 1024 * 1024
"""The most robocal reads of any file (1 GiB): the limit of data tables (measurement CSVs, pose tables)."""

MAX_DOCUMENT_BYTES = 8 * 1024 * 1024
"""The most robocal reads of a structured document (8 MiB): calibration files of every format, robot profiles,
LeRobot calibration JSON, UR kinematics / DH / deltas YAML and ``calibration.conf``, camera_info YAML, a
dataset's ``meta/info.json`` and ``meta/stats.json``. A calibration of 8 MiB holds some 100 000 joints (robots
have tens). Measured: reading an 8 MiB YAML calibration takes about 360 MB, and converting one into an existing
8 MiB YAML file (updated in place) stays within 1 GiB of address space."""

MAX_URDF_BYTES = 16 * 1024 * 1024
"""The most robocal reads of a URDF (16 MiB, some 50 000 joints; real URDFs are well under 1 MiB, their meshes
are separate files). Parsing one takes at most about 300 MB."""


def _mib(n: int) -> str:
    return f"{n / (1024 * 1024):.0f} MiB" if n >= 1024 * 1024 else f"{n} bytes"


def read_bytes(path: PathLike, what: str = "file", *, limit: int | None = None) -> bytes:
    """Read a whole file, turning OS errors into :class:`~robocal.errors.FileFormatError`.

    Args:
        path: File to read.
        what: Human name of the file's role, used in the error message (e.g. ``"URDF"``).
        limit: Most bytes to read (default :data:`MAX_FILE_BYTES`); a larger file is refused before it is read,
            and a pipe or special file that turns out larger is refused after ``limit + 1`` bytes.

    Returns:
        The file's bytes.

    Raises:
        FileFormatError: The file is missing, unreadable, a directory, larger than ``limit``, or its name is
            not a possible file name (a lone surrogate, a NUL byte, too long).
    """
    p = Path(path)
    cap = MAX_FILE_BYTES if limit is None else limit
    try:
        size = p.stat().st_size
        if p.is_dir():
            raise FileFormatError(f"{what} {p}: is a directory, expected a file")
        if size > cap:
            raise FileFormatError(_too_large(what, p, size, cap))
        with p.open("rb") as fh:
            data = _read_bounded(fh, size, cap)
        if len(data) > cap:  # a pipe or a file that grew
            raise FileFormatError(_too_large(what, p, None, cap))
        return data
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


def _read_bounded(fh: BinaryIO, size: int, cap: int) -> bytes:
    """At most ``cap + 1`` bytes, never asking for more than the file holds plus one at a time.

    ``read(n)`` allocates ``n`` bytes first, so ``read(cap + 1)`` cost the whole limit (16 MiB for a URDF) on
    every read; a pipe, a special file or a file that grew (more than ``size`` bytes) is read on in 1 MiB chunks.
    """
    data = fh.read(min(cap, size) + 1)
    if len(data) <= size:
        return data
    parts, total = [data], len(data)
    while total <= cap:
        chunk = fh.read(min(1 << 20, cap + 1 - total))
        if not chunk:
            break
        parts.append(chunk)
        total += len(chunk)
    return b"".join(parts)


def _too_large(what: str, p: Path, size: int | None, cap: int) -> str:
    """``size`` None: a pipe or special file found larger than ``cap`` while reading."""
    if cap == MAX_FILE_BYTES:
        limit = f"robocal's {cap} byte input limit"
    else:
        limit = f"robocal's {cap} byte ({_mib(cap)}) limit for a {what}"
    if size is None:
        return f"{what} {p}: more than {cap} bytes, {limit}"
    return f"{what} {p}: {size} bytes is larger than {limit}"


def read_text(path: PathLike, what: str = "file", *, limit: int | None = None) -> str:
    """Read a UTF-8 text file of at most ``limit`` bytes; see :func:`read_bytes` for the errors raised."""
    data = read_bytes(path, what, limit=limit)
    try:
        return data.decode("utf-8-sig")
    except UnicodeDecodeError as exc:
        raise FileFormatError(f"{what} {path}: not UTF-8 text (byte {exc.start})") from None
