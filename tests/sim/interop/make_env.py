"""Build (or find) the virtual environment with LeRobot 0.6.1 used by the interop tests.

``python tests/sim/interop/make_env.py`` prints the environment's Python on the last line, or ``SKIP: <reason>``.
The environment holds ``lerobot==0.6.1`` installed without its dependencies plus only what its motor buses and
robot classes import (:data:`REQUIREMENTS`); ``torch`` and the other heavy imports get stand-ins from
``harness/interop_stubs.py`` at run time (in the harness only, never in robocal). It needs Python ≥ 3.12.

Cache: ``$ROBOCAL_INTEROP_CACHE`` or ``~/.cache/robocal-interop``, one folder per key (LeRobot version, Python
version, requirements), reused between runs; delete the folder to rebuild.
"""

from __future__ import annotations

import hashlib
import os
import shutil
import subprocess
import sys
import time
from pathlib import Path

LEROBOT = "lerobot==0.6.1"
REQUIREMENTS = (
    "draccus>=0.11.6,<0.12",
    "numpy>=2.0,<2.3",
    "pyserial>=3.5,<4",
    "deepdiff>=7.0.1,<9",
    "feetech-servo-sdk>=1.0,<2",
    "dynamixel-sdk>=3.7.31,<3.9",
    "tqdm>=4.66,<5",
    "termcolor>=2.4,<4",
    "packaging>=24.2,<26",
    "python-can>=4.2.0,<5.0.0",
)
"""LeRobot's own pins (its core and its feetech/dynamixel/damiao extras) for what its motor and robot code imports."""


def cache_root() -> Path:
    return Path(os.environ.get("ROBOCAL_INTEROP_CACHE", "~/.cache/robocal-interop")).expanduser()


def find_python() -> tuple[str, str] | None:
    """A Python ≥ 3.12 on this machine: (path, "3.12"), newest-but-one first (3.12, then 3.13)."""
    candidates: list[str] = []
    for name in ("python3.12", "python3.13"):
        found = shutil.which(name)
        if found:
            candidates.append(found)
    pyenv = Path(os.environ.get("PYENV_ROOT", "~/.pyenv")).expanduser() / "versions"
    if pyenv.is_dir():
        for v in sorted(pyenv.iterdir()):
            if v.name.startswith(("3.12", "3.13")):
                candidates.append(str(v / "bin" / "python3"))
    for exe in candidates:
        try:
            out = subprocess.run(
                [exe, "-c", "import sys, venv; print('%d.%d' % sys.version_info[:2])"],
                capture_output=True,
                text=True,
                timeout=30,
            )
        except (OSError, subprocess.TimeoutExpired):
            continue
        ver = out.stdout.strip()
        if out.returncode == 0 and ver in ("3.12", "3.13"):
            return exe, ver
    return None


def env_python() -> tuple[Path | None, str]:
    """The interop environment's Python (built if missing), or None and the reason."""
    found = find_python()
    if found is None:
        return None, "no Python >= 3.12 on this machine (LeRobot 0.6.1 needs it)"
    exe, ver = found
    digest = hashlib.sha256("\n".join((LEROBOT, *REQUIREMENTS)).encode()).hexdigest()[:10]
    folder = cache_root() / f"{LEROBOT.replace('==', '-')}-py{ver}-{digest}"
    python = folder / "bin" / "python"
    if (folder / ".ready").exists():
        return python, f"reused {folder}"
    start = time.monotonic()
    tmp = folder.with_name(f"{folder.name}.building-{os.getpid()}")
    shutil.rmtree(tmp, ignore_errors=True)
    tmp.parent.mkdir(parents=True, exist_ok=True)
    try:
        subprocess.run([exe, "-m", "venv", "--without-pip", str(tmp)], check=True, capture_output=True)
        pip = [
            sys.executable,
            "-m",
            "pip",
            "--python",
            str(tmp / "bin" / "python"),
            "install",
            "-q",
            "--disable-pip-version-check",
        ]
        subprocess.run([*pip, "--no-deps", LEROBOT], check=True, capture_output=True, text=True)
        subprocess.run([*pip, *REQUIREMENTS], check=True, capture_output=True, text=True)
    except subprocess.CalledProcessError as exc:
        shutil.rmtree(tmp, ignore_errors=True)
        return None, f"cannot build the interop environment: {(exc.stderr or '')[-500:]}"
    (tmp / ".ready").write_text(f"{LEROBOT}\n" + "\n".join(REQUIREMENTS) + "\n")
    try:
        tmp.rename(folder)
    except OSError:  # another run built it meanwhile
        shutil.rmtree(tmp, ignore_errors=True)
    size = sum(f.stat().st_size for f in folder.rglob("*") if f.is_file() and not f.is_symlink())
    return python, f"built {folder} in {time.monotonic() - start:.0f} s, {size / 1e6:.0f} MB"


if __name__ == "__main__":
    py, note = env_python()
    print(note)
    print(py if py is not None else f"SKIP: {note}")
