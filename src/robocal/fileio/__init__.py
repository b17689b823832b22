"""Safe file reading and atomic writing shared by every file format and workflow.

Writes go to a temporary file with a short name (``.rc-<pid>-XXXXXXXX.tmp``) in the target's folder, are flushed and
fsynced, and the temporary file is renamed over the target, so a reader never sees half a file and a failure
leaves the old file untouched. The previous file is kept as a backup, made just as atomically: it is hard-linked
(or, where links are impossible, copied to a temporary file and fsynced) under a temporary name first, and only
then renamed into place, so a full disk never replaces a good backup with a truncated one. A process killed
mid-write (SIGKILL, a power cut) leaves its temporary file; the next write in that folder removes the temporary
files of robocal processes that no longer exist (:func:`remove_stale_temporaries`).

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

from ._paths import BACKUP_GENERATIONS, backup_path, backup_paths
from .preflight import OutputTarget, check_not_an_input, check_output_path, preflight_output
from .read import MAX_DOCUMENT_BYTES, MAX_FILE_BYTES, MAX_URDF_BYTES, read_bytes, read_text
from .write import (
    WriteResult,
    atomic_write,
    atomic_write_bytes,
    atomic_write_text,
    files_written,
    process_gone,
    remove_stale_temporaries,
)

__all__ = [
    "BACKUP_GENERATIONS",
    "MAX_DOCUMENT_BYTES",
    "MAX_FILE_BYTES",
    "MAX_URDF_BYTES",
    "OutputTarget",
    "WriteResult",
    "atomic_write",
    "atomic_write_bytes",
    "atomic_write_text",
    "backup_path",
    "backup_paths",
    "check_not_an_input",
    "check_output_path",
    "files_written",
    "preflight_output",
    "process_gone",
    "read_bytes",
    "read_text",
    "remove_stale_temporaries",
]
