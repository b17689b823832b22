"""Shared pieces of the viewer tests: small URDFs written into tmp_path, waiting for a page's state, a served page
stopped by Ctrl-C."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from collections.abc import Callable
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]
LITE_URDF = REPO / "examples" / "lite" / "lite_bimanual.urdf"

TWO_JOINT = """<?xml version="1.0"?>
<robot name="two">
  <link name="base"/>
  <link name="upper"><visual><origin xyz="0 0 0.1"/><geometry><box size="0.02 0.02 0.2"/></geometry></visual></link>
  <link name="lower"><visual><geometry><cylinder radius="0.01" length="0.2"/></geometry></visual></link>
  <joint name="shoulder" type="revolute">
    <parent link="base"/><child link="upper"/><origin xyz="0 0 0.1"/><axis xyz="0 1 0"/>
    <limit lower="-1.0" upper="1.0" effort="1" velocity="1"/>
  </joint>
  <joint name="elbow" type="revolute">
    <parent link="upper"/><child link="lower"/><origin xyz="0 0 0.2" rpy="0 0.3 0"/><axis xyz="0 1 0"/>
    <limit lower="-2.0" upper="0.5" effort="1" velocity="1"/>
  </joint>
</robot>
"""


@pytest.fixture
def two_joint_urdf(tmp_path: Path) -> Path:
    p = tmp_path / "two.urdf"
    p.write_text(TWO_JOINT)
    return p


def wait_for(cond: Callable[[], bool], timeout_s: float = 60.0) -> None:
    """Poll ``cond`` every 20 ms until it holds; AssertionError after ``timeout_s`` (a generous bound)."""
    end = time.monotonic() + timeout_s
    while not cond():
        if time.monotonic() > end:
            raise AssertionError("condition not reached in time")
        time.sleep(0.02)


def default_sigint() -> None:
    """The child gets Ctrl-C even when the suite runs as a background job (which ignores SIGINT)."""
    signal.signal(signal.SIGINT, signal.SIG_DFL)


def serve_then_ctrl_c(args: list[str], ready: str) -> tuple[list[str], int, str, str]:
    """Run ``python -m robocal ARGS``, read its stdout up to the line starting with ``ready``, then Ctrl-C it.

    Returns:
        The lines read up to and with the ``ready`` line, the exit code, the rest of stdout and all of stderr.
    """
    env = dict(os.environ, PYTHONPATH=str(REPO / "src"))
    proc = subprocess.Popen(
        [sys.executable, "-m", "robocal", *args],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        env=env,
        preexec_fn=default_sigint,
    )
    try:
        assert proc.stdout is not None
        lines = []
        for line in proc.stdout:
            lines.append(line)
            if line.startswith(ready):
                break
        assert lines and lines[-1].startswith(ready), "".join(lines[-5:])
        proc.send_signal(signal.SIGINT)
        out, err = proc.communicate(timeout=60)
    finally:
        if proc.poll() is None:
            proc.kill()
    return lines, proc.returncode, out, err
