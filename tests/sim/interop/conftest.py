"""The interop suite: LeRobot 0.6.1's own code, in its own virtual environment, against ``robocal sim``.

The environment is built once by ``make_env.py`` (cached, see there); without a Python ≥ 3.12 on the machine
the tests are skipped with that reason.
"""

from __future__ import annotations

import json
import os
import subprocess
from pathlib import Path

import pytest

from ..conftest import Interactive, SimProcess, robocal, sim_process
from .make_env import env_python

__all__ = ["Interactive", "SimProcess", "robocal", "sim_process"]

HARNESS = Path(__file__).with_name("harness")
CLIENTS = Path(__file__).with_name("clients")


@pytest.fixture(scope="session")
def lerobot_python() -> Path:
    python, note = env_python()
    if python is None:
        pytest.skip(note)
    print(f"interop environment: {note}")
    return python


def harness_argv(python: Path, action: str, **args: object) -> list[str]:
    return [str(python), "-u", str(HARNESS / "lerobot_harness.py"), action, json.dumps(args)]


def harness_env() -> dict[str, str]:
    return dict(os.environ, PYTHONPATH=str(HARNESS), PYTHONNOUSERSITE="1")


def run_harness(python: Path, action: str, cwd: Path, **args: object) -> dict:
    r = subprocess.run(
        harness_argv(python, action, **args),
        cwd=cwd,
        env=harness_env(),
        capture_output=True,
        text=True,
        timeout=180,
    )
    assert r.returncode == 0, r.stdout[-2000:] + r.stderr[-3000:]
    return result_of(r.stdout)


def result_of(output: str) -> dict:
    """The object of the last ``RESULT {json}`` line a harness or client script printed."""
    line = next(x for x in reversed(output.splitlines()) if x.startswith("RESULT "))
    return json.loads(line[len("RESULT ") :])


def run_client(python: Path, script: str, args: dict[str, object], env: dict[str, str] | None = None) -> dict:
    """Run ``clients/<script>`` with ``args`` (one JSON argument) in a third-party client's own environment.

    Neither robocal nor the user's site packages are on its path; ``env`` is added to this process's environment.
    Fails the test with the script's output when it exits non-zero; returns its ``RESULT`` object.
    """
    r = subprocess.run(
        [str(python), "-u", str(CLIENTS / script), json.dumps(args)],
        capture_output=True,
        text=True,
        timeout=180,
        env=dict(os.environ, PYTHONNOUSERSITE="1", PYTHONPATH="", **(env or {})),
    )
    assert r.returncode == 0, r.stdout[-2000:] + r.stderr[-3000:]
    return result_of(r.stdout)


def client_env_python(name: str) -> Path:
    """The Python of a third-party client's own environment (built once, cached; see client_envs.py), or skip with
    the reason the client cannot be installed here."""
    from .client_envs import client_python

    python, note = client_python(name)
    if python is None:
        pytest.skip(note)
    return python
