"""Register snapshots kept on disk while a guarded run may leave motors changed (issue 26).

One JSON file per bus in robocal's state folder, ``$XDG_STATE_HOME/robocal/left-changed/`` (default
``~/.local/state/robocal/left-changed/``; the folder the crash logs go to): written before the first register
changes, removed when the run ends cleanly or everything was written back. A run killed with SIGKILL, a power cut
or a lost device leaves it behind; the next command that opens that bus finds it (:func:`find_left_changed`), says
which registers differ from it and offers to write them back.
"""

from __future__ import annotations

import contextlib
import hashlib
import json
import os
import tempfile
import time
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

__all__ = ["LeftChanged", "SnapshotStore", "find_left_changed", "state_dir"]


def state_dir() -> Path:
    """``$XDG_STATE_HOME/robocal`` (default ``~/.local/state/robocal``)."""
    state = os.environ.get("XDG_STATE_HOME") or os.path.join(os.path.expanduser("~"), ".local", "state")
    return Path(state) / "robocal"


def _port_key(port: str) -> str:
    """The bus's file name: the port's real path (a symbolic link and its target are one bus), readable + hash."""
    real = os.path.realpath(port) if not port.startswith(("inproc://", "sim")) else port
    safe = "".join(c if c.isalnum() or c in "-_." else "_" for c in real).strip("_")[-60:]
    return f"{safe}-{hashlib.sha256(real.encode()).hexdigest()[:10]}"


@dataclass(frozen=True)
class LeftChanged:
    """A snapshot a previous run left behind.

    Attributes:
        path: The file.
        port: The bus it was taken on.
        command: The command that took it.
        pid: Its process id.
        time_utc: When (ISO 8601).
        registers: Motor name → register → value before that run changed them.
        about: Everything else the run stored (robot, motor ids…).
    """

    path: Path
    port: str
    command: str
    pid: int
    time_utc: str
    registers: dict[str, dict[str, int]]
    about: dict[str, Any]


class SnapshotStore:
    """The snapshot file of one bus (``port``)."""

    def __init__(self, port: str, command: str) -> None:
        self.port, self.command = port, command
        self.path = state_dir() / "left-changed" / f"{_port_key(port)}.json"

    def save(self, registers: Mapping[str, Mapping[str, int]], **about: object) -> None:
        """Write the snapshot (temporary file, fsync, rename); a folder that cannot be written is skipped."""
        doc = {
            "port": self.port,
            "command": self.command,
            "pid": os.getpid(),
            "time_utc": time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime()),
            "registers": {m: dict(r) for m, r in registers.items()},
            "about": about,
        }
        data = json.dumps(doc, indent=1, default=str).encode()
        with contextlib.suppress(OSError):  # the state folder is a convenience, never a reason to stop
            self.path.parent.mkdir(parents=True, exist_ok=True)
            fd, tmp = tempfile.mkstemp(prefix=".snapshot-", dir=self.path.parent)
            try:
                with os.fdopen(fd, "wb") as fh:
                    fh.write(data)
                    fh.flush()
                    os.fsync(fh.fileno())
                os.replace(tmp, self.path)
            finally:
                with contextlib.suppress(OSError):
                    os.unlink(tmp)

    def exists(self) -> bool:
        """Whether the file is there."""
        return self.path.is_file()

    def remove(self) -> None:
        """Remove the file (nothing is left changed)."""
        with contextlib.suppress(OSError):
            self.path.unlink()


def find_left_changed(port: str) -> LeftChanged | None:
    """The snapshot a previous run left for ``port`` (None: none, or one that cannot be read)."""
    path = SnapshotStore(port, "").path
    try:
        doc = json.loads(path.read_text(encoding="utf-8"))
        registers = {
            str(m): {str(r): int(v) for r, v in regs.items()} for m, regs in dict(doc["registers"]).items()
        }
        return LeftChanged(
            path,
            str(doc.get("port", port)),
            str(doc.get("command", "")),
            int(doc.get("pid", 0)),
            str(doc.get("time_utc", "")),
            registers,
            dict(doc.get("about", {})),
        )
    except (OSError, ValueError, TypeError, KeyError, AttributeError):
        return None
