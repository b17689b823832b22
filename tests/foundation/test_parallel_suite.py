"""The suite runs on both cores (pytest-xdist, issue 28): the settings that make it so, and the way out of it.

``pyproject.toml``'s addopts give every ``pytest`` run ``-n auto --dist worksteal``; ``tests/conftest.py`` caps
``auto`` at two workers and keeps the same commands working where pytest-xdist is not loaded.
"""

from __future__ import annotations

import ast
import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
PYPROJECT = (ROOT / "pyproject.toml").read_text(encoding="utf-8")  # read as text: no tomllib on Python 3.10


def _conftest_module():  # type: ignore[no-untyped-def]
    """tests/conftest.py as pytest loaded it (importlib mode: looked up by its file, not by a package name)."""
    path = str(ROOT / "tests" / "conftest.py")
    return next(m for m in list(sys.modules.values()) if getattr(m, "__file__", None) == path)


def test_xdist_is_in_the_test_extra_and_on_by_default() -> None:
    extra = PYPROJECT.split("\ntest = [\n", 1)[1].split("\n]\n", 1)[0]
    assert re.search(r'^    "pytest-xdist>=[0-9.]+",', extra, re.M), extra
    addopts = ast.literal_eval(re.search(r"^addopts = (\[.*\])$", PYPROJECT, re.M).group(1))  # type: ignore[union-attr]
    assert addopts[addopts.index("-n") + 1] == "auto"
    assert addopts[addopts.index("--dist") + 1] == "worksteal"
    assert "--durations=20" in addopts  # the 20 slowest tests, printed by the controller for all workers


@pytest.mark.parametrize(("cpus", "workers"), [(1, 1), (2, 2), (64, 2)])
def test_auto_is_the_usable_cpus_at_most_two(monkeypatch: pytest.MonkeyPatch, cpus: int, workers: int) -> None:
    conftest = _conftest_module()
    monkeypatch.delenv("PYTEST_XDIST_AUTO_NUM_WORKERS", raising=False)
    monkeypatch.setattr(os, "sched_getaffinity", lambda _pid: set(range(cpus)))
    assert conftest.pytest_xdist_auto_num_workers(None) == workers
    monkeypatch.setenv("PYTEST_XDIST_AUTO_NUM_WORKERS", "5")
    assert conftest.pytest_xdist_auto_num_workers(None) is None  # xdist's own rule then reads the variable


@pytest.mark.skipif("ROBOCAL_TESTS_KEEP_XDG_STATE" in os.environ, reason="the run keeps its own XDG_STATE_HOME")
def test_each_test_has_its_own_state_folder_in_every_worker() -> None:
    state = os.environ["XDG_STATE_HOME"]
    assert Path(state).name.startswith("robocal-tests-state-") and Path(state).is_dir()
    assert not any(Path(state).iterdir())  # fresh for this test, whichever worker runs it


def test_without_xdist_the_configured_options_are_accepted_and_tests_run_here() -> None:
    r = subprocess.run(
        [sys.executable, "-m", "pytest", "-p", "no:xdist", "-p", "no:cacheprovider", "-q",
         f"{Path(__file__).relative_to(ROOT)}::test_xdist_is_in_the_test_extra_and_on_by_default"],
        cwd=ROOT,
        capture_output=True,
        text=True,
        timeout=120,
        check=False,
    )  # fmt: skip
    assert r.returncode == 0, r.stdout[-2000:] + r.stderr[-2000:]
    assert "1 passed" in r.stdout and "workers" not in r.stdout
