"""Bounded reads: a whole file, or UTF-8 text, with every OS error a :class:`~robocal.errors.FileFormatError`."""

from __future__ import annotations

from pathlib import Path

from ..errors import FileFormatError
from ._paths import PathLike

__all__ = ["MAX_FILE_BYTES", "read_bytes", "read_text"]

MAX_FILE_BYTES = 1024 * 1024 * 1024
"""Refuse to read calibration or description files larger than this (1 GiB: a URDF of a million joints is
about 300 MB, the largest file a robot can plausibly need)."""


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
