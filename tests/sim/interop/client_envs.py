"""Build (or find) one virtual environment per third-party client library the interop tests drive.

``python tests/sim/interop/client_envs.py [NAME…]`` builds them (all by default) and prints one line per client:
its Python, or ``SKIP <name>: <reason>``. Each environment holds exactly the pinned client and its dependencies
(:data:`CLIENT_ENVS`), from the package index pip is configured with, and never robocal: the harness scripts in
``clients/`` run there and talk to ``robocal sim`` over a real socket or pseudo-terminal only.

Cache: ``$ROBOCAL_INTEROP_CACHE`` or ``~/.cache/robocal-interop``, one folder per client and key (requirements and
Python version), reused between runs; delete the folder to rebuild. The Python is the one running this file (the
project's 3.10+), so a client without a wheel or source build for it is skipped with pip's own error.
"""

from __future__ import annotations

import fcntl
import hashlib
import os
import shutil
import subprocess
import sys
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

__all__ = ["CLIENT_ENVS", "ClientEnv", "client_python"]


def cache_root() -> Path:
    """Where the environments live (as make_env.py's LeRobot one)."""
    return Path(os.environ.get("ROBOCAL_INTEROP_CACHE", "~/.cache/robocal-interop")).expanduser()


@dataclass(frozen=True)
class ClientEnv:
    """A third-party client's environment.

    Attributes:
        requirements: What pip installs (pinned).
        imports: Modules imported once after the install, to check it.
        unusable: Checked first; its reason, if any, skips the client without building it.
    """

    requirements: tuple[str, ...]
    imports: tuple[str, ...]
    unusable: Callable[[], str | None] | None = None
    """Why the client could not be used on this machine even if it installed (None: it can; not built then)."""


CLIENT_ENVS: dict[str, ClientEnv] = {
    "robstride": ClientEnv(("robstride==0.1.0", "python-can==4.6.1"), ("robstride.client", "can")),
    "ur_rtde": ClientEnv(("ur-rtde==1.6.5",), ("rtde_receive", "dashboard_client")),
    # urx 0.11 with the math3d pip picks (4.0): its getl/get_pose break there; math3d 3.x does not import on 3.10+
    "urx": ClientEnv(("urx==0.11.0",), ("urx",)),
    "dynamixel_sdk": ClientEnv(("dynamixel-sdk==4.1.0",), ("dynamixel_sdk",)),
    "st3215": ClientEnv(("st3215==0.4.2",), ("st3215",)),
    "feetech_cli": ClientEnv(("feetech-cli==0.1.8",), ("feetech_cli",)),
    "damiao_motor": ClientEnv(("damiao-motor==1.0.6", "python-can==4.6.1"), ("damiao_motor", "can")),
    # an sdist only: its build clones enactic/openarm_can's C++ library from GitHub (CMake FetchContent), so it
    # builds only where that host is reached; it then speaks raw SocketCAN (AF_CAN), see test_client_openarm_can.py
    "openarm_can": ClientEnv(("openarm-can==1.4.1",), ("openarm_can",), unusable=lambda: _no_socketcan()),
}
"""Client → its environment (the versions issue 29 names, or the newest the index serves)."""


def _no_socketcan() -> str | None:
    """Why this kernel cannot carry SocketCAN frames (None: it can)."""
    import socket

    family = getattr(socket, "AF_CAN", None)
    if family is None:
        return "this Python has no socket.AF_CAN (not Linux)"
    try:
        socket.socket(family, socket.SOCK_RAW, socket.CAN_RAW).close()
    except OSError as exc:
        return f"it needs SocketCAN and this kernel has none ({exc.strerror}: AF_CAN; no vcan module)"
    return None


def client_python(name: str) -> tuple[Path | None, str]:
    """The client's environment's Python (built if missing), or None and the reason (pip's error, or why it could
    not be used here)."""
    env = CLIENT_ENVS[name]
    why = env.unusable() if env.unusable is not None else None
    if why is not None:
        return None, f"{name}: {why}"
    ver = f"{sys.version_info[0]}.{sys.version_info[1]}"
    digest = hashlib.sha256("\n".join(env.requirements).encode()).hexdigest()[:10]
    folder = cache_root() / f"client-{name}-py{ver}-{digest}"
    python = folder / "bin" / "python"
    if _usable(folder):
        return python, f"reused {folder}"
    folder.parent.mkdir(parents=True, exist_ok=True)
    # built in place (console scripts name their interpreter by its absolute path), one builder at a time
    with open(folder.with_name(folder.name + ".lock"), "w") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)
        if _usable(folder):
            return python, f"reused {folder}"
        return _build(folder, env)


def _usable(folder: Path) -> bool:
    """Built, and its interpreter still there (an environment made from a Python that is gone is rebuilt)."""
    return (folder / ".ready").exists() and (folder / "bin" / "python").exists()  # exists() follows the link


def _build(folder: Path, env: ClientEnv) -> tuple[Path | None, str]:
    start = time.monotonic()
    python = folder / "bin" / "python"
    shutil.rmtree(folder, ignore_errors=True)
    pip = [
        sys.executable,
        "-m",
        "pip",
        "--python",
        str(python),
        "install",
        "-q",
        "--disable-pip-version-check",
    ]
    try:
        # from the base interpreter, not the test run's virtual environment: that one lives in the project's
        # clone, and a cached environment made from it broke when a CI clone was deleted (its python a dangling link)
        base = Path(sys.base_prefix, "bin", f"python{sys.version_info[0]}.{sys.version_info[1]}")
        base = base if base.exists() else Path(sys.executable)  # (sys._base_executable is the venv's on 3.10)
        subprocess.run([base, "-m", "venv", "--without-pip", str(folder)], check=True, capture_output=True)
        subprocess.run([*pip, *env.requirements], check=True, capture_output=True, text=True, timeout=900)
        check = "; ".join(f"import {m}" for m in env.imports)
        subprocess.run([str(python), "-c", check], check=True, capture_output=True, text=True)
    except subprocess.CalledProcessError as exc:
        shutil.rmtree(folder, ignore_errors=True)
        errors = [line for line in (exc.stderr or "").splitlines() if "ERROR" in line or "Error" in line]
        return None, f"cannot install {' '.join(env.requirements)}: {' | '.join(errors[-3:]) or exc}"
    except subprocess.TimeoutExpired:
        shutil.rmtree(folder, ignore_errors=True)
        return None, f"installing {' '.join(env.requirements)} took over 900 s"
    (folder / ".ready").write_text("\n".join(env.requirements) + "\n")
    return python, f"built {folder} in {time.monotonic() - start:.0f} s"


if __name__ == "__main__":
    for client in sys.argv[1:] or list(CLIENT_ENVS):
        py, note = client_python(client)
        print(f"{client}: {py}  ({note})" if py is not None else f"SKIP {client}: {note}")
