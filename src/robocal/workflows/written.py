"""What this process has written: the CLI's account of an interruption names these files (each is whole)."""

from __future__ import annotations

from pathlib import Path

from ..fileio import files_written as _files_written

__all__ = ["files_written"]


def files_written() -> tuple[Path, ...]:
    """Every file robocal wrote (atomically, so each is complete) in this process, oldest first."""
    return _files_written()
