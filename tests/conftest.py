"""Test-suite wide settings."""

from __future__ import annotations

import os
import signal
import tempfile

import pytest
from hypothesis import HealthCheck, settings

# The suite's own runs (the README command, the fast tier, CI) draw the same examples every time
# (derandomize=True, no example database): a red run is red for the code, not for a new random draw, and the
# next run reproduces it. Exploring is a separate run: HYPOTHESIS_PROFILE=random (the same counts, fresh random
# examples, remembered failures in .hypothesis/) or thorough (1000 examples per property, random; tests/fuzz:
# ~100x, see fuzzlib).
settings.register_profile(
    "default",
    max_examples=60,
    deadline=None,
    derandomize=True,
    database=None,
    print_blob=True,
    suppress_health_check=[HealthCheck.too_slow],
)
settings.register_profile("random", max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow])
settings.register_profile("thorough", max_examples=1000, deadline=None)
settings.load_profile(os.environ.get("HYPOTHESIS_PROFILE", "default"))

# A shell started in the background without job control (``cmd &`` in a script, nohup, some CI runners) starts
# its children with SIGINT and SIGQUIT ignored, and Python then installs no KeyboardInterrupt handler: every
# Ctrl-C test (a real SIGINT to this process or to a robocal subprocess) and every SIGQUIT test would fail (hang
# until its timeout) for a reason outside robocal. Put the interactive defaults back; subprocesses inherit them
# (an ignored signal is inherited across exec, a handler is not). An ignored SIGHUP (nohup) is left alone.
if signal.getsignal(signal.SIGINT) is signal.SIG_IGN:
    signal.signal(signal.SIGINT, signal.default_int_handler)
if hasattr(signal, "SIGQUIT") and signal.getsignal(signal.SIGQUIT) is signal.SIG_IGN:
    signal.signal(signal.SIGQUIT, signal.SIG_DFL)

# The suite runs on both cores (pytest-xdist, ``-n auto --dist worksteal`` in pyproject's addopts; each worker is its own
# process and runs this file, so the settings above and below hold in every worker). ``-n auto`` means at most two
# workers here: the suite's time limits and its tests' tolerances are set on 2 cores, a test often starts one to
# three processes of its own (a simulator, robocal, a client), and ``os.cpu_count()`` ignores a container's CPU
# quota (a CI container on a large host would start dozens of workers on two CPUs). More: ``-n 4``; one test
# alone, in this process (a debugger, a Ctrl-C test by hand): ``-n 0``. ``--pdb`` turns ``auto`` into no workers.
MAX_AUTO_WORKERS = 2


@pytest.hookimpl(optionalhook=True)
def pytest_xdist_auto_num_workers(config: pytest.Config) -> int | None:
    """``-n auto``: the usable CPUs, at most :data:`MAX_AUTO_WORKERS` (``$PYTEST_XDIST_AUTO_NUM_WORKERS`` wins)."""
    if os.environ.get("PYTEST_XDIST_AUTO_NUM_WORKERS"):
        return None  # xdist's own rule reads it
    cpus = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else (os.cpu_count() or 1)
    return max(1, min(MAX_AUTO_WORKERS, cpus))


def pytest_addoption(parser: pytest.Parser, pluginmanager: pytest.PytestPluginManager) -> None:
    """Without pytest-xdist (not installed, or ``-p no:xdist``) pyproject's ``-n``/``--dist`` are accepted and the
    tests run one after another in this process, instead of pytest refusing its own configuration."""
    if pluginmanager.has_plugin("xdist"):
        return
    group = parser.getgroup("xdist-absent", "pytest-xdist is not loaded: the tests run in this process")
    group._addoption("-n", "--numprocesses", dest="numprocesses", default=None, help="ignored (no pytest-xdist)")
    group._addoption("--dist", dest="dist", default="no", help="ignored (no pytest-xdist)")


# robocal keeps register snapshots (and crash logs) in $XDG_STATE_HOME/robocal: a test run must not leave them in
# the home folder of whoever runs it. One folder for the whole session (subprocesses inherit it); a test that
# checks the snapshots sets its own.
if "ROBOCAL_TESTS_KEEP_XDG_STATE" not in os.environ:
    os.environ["XDG_STATE_HOME"] = tempfile.mkdtemp(prefix="robocal-tests-state-")


@pytest.fixture(autouse=True)
def _fresh_state_folder(monkeypatch: pytest.MonkeyPatch) -> None:
    """Each test its own ``$XDG_STATE_HOME``: a snapshot a killed robocal left for a pty name is not found by a
    later test that gets the same pty name (a test that checks the snapshots sets its own folder on top)."""
    if "ROBOCAL_TESTS_KEEP_XDG_STATE" not in os.environ:
        monkeypatch.setenv("XDG_STATE_HOME", tempfile.mkdtemp(prefix="robocal-tests-state-"))
