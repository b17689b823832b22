"""A signal that comes while ``sweep --auto`` fails on its own wins: exit 128 + signal, never the fault's 3 (issue 26).

The Damiao soak of 2026-11-29 had a search fail by itself under load just as SIGTERM came: exit 3 where 143 was
expected. The motion guard makes every motor limp after a fault with signals held off (a signal must not cut the
limp short) and then re-raised the fault; the signal, counted, was never acted on. Here ``robocal`` runs as its
own process (its own signal handlers) on the in-process simulated OpenArm, a motor fails after 300 exchanges
(a ``DeviceError``: the run aborts), and the process signals itself at the instant the guard's limp begins.
Judged by the exit code, the one line and the simulated motors (every one limp, TIMEOUT put back).
"""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
from importlib import resources
from pathlib import Path

import pytest

pytest.importorskip("can")

SRC = Path(__file__).resolve().parents[2] / "src"
URDF = Path(str(resources.files("robocal").joinpath("data", "openarm_v10_right.urdf")))
CHILD = """
import atexit, json, os, signal, sys
signum, state_path = int(sys.argv[1]), sys.argv[2]
sys.argv = ["robocal", *sys.argv[3:]]
import robocal.workflows.autocal.damiao as oa
import robocal.workflows.autocal.sweep as sw
from robocal.backends.damiao.joint_driver import DamiaoJointDriver
from robocal.errors import DeviceError
arms = []
real_open = oa.open_sim_openarm
def open_sim(*a, **k):
    sim = real_open(*a, **k)
    arms.append(sim.arm)
    return sim
oa.open_sim_openarm = open_sim
exchanges = [0]
real_exchange = DamiaoJointDriver._exchange
def exchange(self, target):
    exchanges[0] += 1
    if exchanges[0] == 300:
        raise DeviceError("injected: the motor fails")
    return real_exchange(self, target)
DamiaoJointDriver._exchange = exchange
real_limp_all, limps = sw.limp_all, [0]
def limp_all(drivers):
    limps[0] += 1
    if limps[0] == 1:  # the guard's limp after the fault (its signals held off meanwhile)
        os.kill(os.getpid(), signum)
    return real_limp_all(drivers)
sw.limp_all = limp_all
def dump():
    with open(state_path, "w") as f:
        json.dump({n: {"enabled": m.enabled, "timeout": m.ram[9]} for n, m in arms[0].motors.items()}, f)
atexit.register(dump)
real_exit = os._exit
def exit_now(code):  # an interrupted command ends by os._exit (no atexit): the state is read first
    dump()
    real_exit(code)
os._exit = exit_now
from robocal.cli.entry import run
run()
"""


@pytest.mark.parametrize(
    ("signum", "line"),
    [
        (signal.SIGTERM, "error: interrupted by SIGTERM"),
        pytest.param(signal.SIGHUP, "error: interrupted by SIGHUP", marks=pytest.mark.slow),
        pytest.param(signal.SIGINT, "error: interrupted", marks=pytest.mark.slow),
    ],
)
@pytest.mark.timeout(300)
def test_a_signal_while_the_guard_limps_after_a_fault_wins_over_the_fault(
    tmp_path: Path, signum: int, line: str
) -> None:
    state = tmp_path / "state.json"
    args = ["sweep", "--auto", "--urdf", str(URDF), "--robot", "openarm_follower_right", "--source",
            "sim:openarm?seed=3", "--out", str(tmp_path / "cal.json"), "--joints", "openarm_right_gripper_motor",
            "--yes"]  # fmt: skip
    proc = subprocess.run(
        [sys.executable, "-c", CHILD, str(int(signum)), str(state), *args],
        env=dict(os.environ, PYTHONPATH=str(SRC), XDG_STATE_HOME=str(tmp_path / "xdg"), COLUMNS="200"),
        stdin=subprocess.DEVNULL, capture_output=True, text=True, timeout=240,
    )  # fmt: skip
    lines = proc.stderr.strip().splitlines()
    assert proc.returncode == 128 + signum, proc.stderr[-2000:]  # before: 3, "auto-calibration aborted ..."
    assert lines[-1] == line and "Traceback" not in proc.stderr
    assert "interrupted: every motor is limp; nothing was written" in proc.stderr
    motors = json.loads(state.read_text())
    assert motors and not any(m["enabled"] for m in motors.values())  # the simulator: every motor limp
    assert all(m["timeout"] == 0 for m in motors.values())  # every TIMEOUT put back
    assert not (tmp_path / "cal.json").exists()
