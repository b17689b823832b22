"""The live view of ``robocal sim`` in a real terminal (tmux): read the screen, press keys as a person would."""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
import time
from collections.abc import Iterator
from pathlib import Path

import pytest

from robocal.backends.sim.control import SimControl

pytestmark = [
    pytest.mark.timeout(240),
    pytest.mark.skipif(shutil.which("tmux") is None, reason="tmux is not installed"),
]


# A private tmux server per test run: a server another program started keeps that program's environment (a
# COLUMNS=80 there cuts the table's joint names off) and its size options.
SOCKET = f"robocal-test-{os.getpid()}"


def _tmux(*args: str) -> str:
    return subprocess.run(["tmux", "-L", SOCKET, *args], check=True, capture_output=True, text=True).stdout


@pytest.fixture
def session(tmp_path: Path) -> Iterator[str]:
    name = f"robocal-sim-{time.monotonic_ns()}"
    cmd = f"cd {tmp_path} && env -u COLUMNS -u LINES {sys.executable} -m robocal sim so101_follower --link arm.port; echo EXITED $?; sleep 30"
    _tmux("new-session", "-d", "-s", name, "-x", "200", "-y", "40", cmd)
    yield name
    subprocess.run(["tmux", "-L", SOCKET, "kill-server"], capture_output=True)


def _screen(name: str) -> str:
    return _tmux("capture-pane", "-p", "-t", name)


def _wait_for(name: str, needle: str, timeout: float = 60.0) -> str:
    """Poll the screen until ``needle`` shows (``timeout`` is a hang guard: start-up is slow on a loaded machine)."""
    deadline = time.monotonic() + timeout
    while True:
        screen = _screen(name)
        if needle in screen:
            return screen
        if time.monotonic() > deadline:
            raise AssertionError(f"{needle!r} not on screen:\n{screen}")
        time.sleep(0.1)


def _row(screen: str, joint: str) -> str:
    return next(line for line in screen.splitlines() if f" {joint} (id" in line)


def test_keys_select_move_and_push_joints_and_q_quits(session: str, tmp_path: Path) -> None:
    screen = _wait_for(session, "shoulder_pan (id 1)")
    assert "port: /dev/pts/" in screen
    assert f"control: {tmp_path}/arm.port.control" in screen
    assert "▶" in _row(screen, "shoulder_pan")
    _tmux("send-keys", "-t", session, "Down")
    screen = _wait_for(session, "▶ │ shoulder_lift")
    _tmux("send-keys", "-t", session, "[")  # push shoulder_lift into its low stop (780 ticks)
    deadline = time.monotonic() + 60.0
    while " 780 " not in _row(_screen(session), "shoulder_lift").replace("│", " ") and time.monotonic() < deadline:
        time.sleep(0.1)  # the view redraws on its own clock: wait for it, however loaded the machine is
    row = _row(_screen(session), "shoulder_lift")
    assert " 780 " in row.replace("│", " "), row
    _tmux("send-keys", "-t", session, "Right", "Right")  # two steps of 20 ticks off the stop
    with SimControl(tmp_path / "arm.port.control") as ctl:
        deadline = time.monotonic() + 60.0
        while (state := ctl.state())["shoulder_lift"]["position"] != 820.0 and time.monotonic() < deadline:
            time.sleep(0.1)
    assert state["shoulder_lift"]["position"] == 820.0
    assert state["shoulder_pan"]["position"] == 2100.0
    _tmux("send-keys", "-t", session, "q")
    screen = _wait_for(session, "EXITED 0")
    assert not (tmp_path / "arm.port").exists()
