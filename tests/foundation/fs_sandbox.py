"""Run Python on a real, small or read-only tmpfs in a private user+mount namespace (``unshare -rm``).

The kernel itself then answers ENOSPC / EROFS, so file-writing tests see real failures. Tests using it are
skipped where unprivileged namespaces are not allowed.
"""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
import textwrap
from pathlib import Path
from typing import Any

import pytest

SRC = str(Path(__file__).resolve().parents[2] / "src")


FILL_DISK = """
try:
    with open(mnt / "fill", "wb") as fh:
        while True:
            fh.write(b"0" * 4096)
            fh.flush()
except OSError:
    pass
"""
"""A ``setup`` snippet for :func:`run_on_tmpfs`: write ``mnt/fill`` until the tmpfs is full (ENOSPC)."""


def _can_unshare() -> bool:
    if shutil.which("unshare") is None:
        return False
    r = subprocess.run(["unshare", "-rm", "true"], capture_output=True, check=False)
    return r.returncode == 0


needs_unshare = pytest.mark.skipif(not _can_unshare(), reason="needs unprivileged user+mount namespaces")


def run_on_tmpfs(
    tmp_path: Path, setup: str, action: str, *, size: str = "64k", read_only: bool = False
) -> dict[str, Any]:
    """Mount a ``size`` tmpfs at ``tmp_path/mnt``, run Python ``setup`` then ``action`` there; return its JSON.

    Both snippets see ``mnt`` (a Path). ``action`` must print one JSON object. With ``read_only`` the tmpfs is
    remounted read-only between the two.
    """
    mnt = tmp_path / "mnt"
    mnt.mkdir()
    head = "import json, os, sys\nfrom pathlib import Path\nmnt = Path(sys.argv[1])\n"
    (tmp_path / "setup.py").write_text(head + textwrap.dedent(setup))
    (tmp_path / "action.py").write_text(head + textwrap.dedent(action))
    py = sys.executable
    remount = f"mount -o remount,ro {mnt} && " if read_only else ""
    script = (
        f"mount -t tmpfs -o size={size} tmpfs {mnt} && {py} {tmp_path / 'setup.py'} {mnt} && "
        f"{remount}{py} {tmp_path / 'action.py'} {mnt}"
    )
    env = {**os.environ, "PYTHONPATH": SRC}
    r = subprocess.run(
        ["unshare", "-rm", "sh", "-c", script], capture_output=True, text=True, env=env, check=False
    )
    assert r.returncode == 0, r.stderr
    return json.loads(r.stdout.strip().splitlines()[-1])


def _can_unshare_user() -> bool:
    if shutil.which("unshare") is None:
        return False
    return subprocess.run(["unshare", "--user", "true"], capture_output=True, check=False).returncode == 0


needs_user_ns = pytest.mark.skipif(not _can_unshare_user(), reason="needs unprivileged user namespaces")


def run_without_privileges(code: str, *args: str) -> dict[str, Any]:
    """Run Python ``code`` without root's permission overrides (``unshare --user``); return its JSON line.

    In a new user namespace without a mapping the process keeps its own files but loses CAP_DAC_OVERRIDE, so
    a folder of mode 0500 is read-only for it as for any user. ``code`` sees ``argv`` (``sys.argv[1:]``).
    """
    head = "import json, os, sys\nfrom pathlib import Path\nargv = sys.argv[1:]\n"
    env = {**os.environ, "PYTHONPATH": SRC}
    r = subprocess.run(
        ["unshare", "--user", sys.executable, "-c", head + textwrap.dedent(code), *args],
        capture_output=True,
        text=True,
        env=env,
        check=False,
    )
    assert r.returncode == 0, r.stderr
    return json.loads(r.stdout.strip().splitlines()[-1])  # type: ignore[no-any-return]
