"""``robocal sim`` and a robocal command on a loaded machine: either process is held up (SIGSTOP, as a starving
scheduler would) in the middle of a calibration's sweep, and the calibration still comes out exact.

Held-up reader: the paced sweep's hand waits until the command read where the joint is, so both stops are seen.
Held-up simulator: the command waits for replies up to ``CLIENT_ENV``'s reply timeout, not a motor's 100 ms.
"""

from __future__ import annotations

import json
import os
import signal
import sys
import time
from pathlib import Path

import pytest

from robocal.backends.sim.control import SimControl

from .conftest import CLIENT_ENV, REPLY_TIMEOUT_ENV, Interactive

pytestmark = pytest.mark.timeout(180)

# the stock SO-101 follower's gripper: stops 2000..3400 actual ticks, held at 2300 for "middle"
GRIPPER = {"id": 6, "drive_mode": 0, "homing_offset": 253, "range_min": 1747, "range_max": 3147}
HELD_UP_S = 1.5
"""How long a process is held up: longer than the whole unpaced sweep's first stop."""


def test_a_command_waits_longer_for_a_reply_than_the_simulator_is_held_up() -> None:
    """The held-up simulator's case needs it: the command's reply timeout outlasts the hold-up."""
    assert float(CLIENT_ENV[REPLY_TIMEOUT_ENV]) / 1000.0 > HELD_UP_S + 0.25


@pytest.mark.slow
@pytest.mark.parametrize("held_up", ["command", "simulator"])
def test_calibration_is_exact_when_a_process_is_held_up_during_the_sweep(
    sim_process, tmp_path: Path, held_up: str
) -> None:
    sim = sim_process(["so101_follower"])
    port = sim.info["port"]
    argv = [
        "lerobot",
        "calibrate",
        "--robot",
        "so101_follower",
        "--port",
        port,
        "--id",
        "x",
        "--calibration-dir",
        "cal",
    ]
    run = Interactive([sys.executable, "-m", "robocal", *argv], tmp_path)
    with SimControl(sim.info["control"]) as ctl:
        k = run.expect("middle of its range of motion")
        ctl.mid()
        run.send()
        run.expect("whole range of motion", after=k)
        ctl.sweep(seconds=1.2, dwell_s=0.2, paced=True, wait=False)
        pid = run.proc.pid if held_up == "command" else sim.proc.pid
        os.kill(pid, signal.SIGSTOP)
        try:
            time.sleep(HELD_UP_S)
        finally:
            os.kill(pid, signal.SIGCONT)
        assert ctl.request("wait", timeout_s=120)["idle"] is True
        run.send()
    code, out = run.finish()
    assert code == 0, out
    assert "full turn" not in out and "seam" not in out, out
    cal = json.loads((tmp_path / "cal/robots/so_follower/x.json").read_text())
    assert cal["gripper"] == GRIPPER
    with SimControl(sim.info["control"]) as ctl:
        state = ctl.state()
    for name, c in cal.items():  # every swept joint's range is its two stops, as the firmware reads them
        if name == "wrist_roll":
            continue  # a full-turn joint: LeRobot keeps 0..4095
        assert c["range_max"] - c["range_min"] == state[name]["high"] - state[name]["low"], name
