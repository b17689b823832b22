"""After a fault the host could not act on: the next run reports what was left changed and restores it (issue 26).

The run's register snapshot stays in robocal's state folder (each trial has its own ``XDG_STATE_HOME``) when a
SIGKILL, a lost device or a frozen one kept robocal from writing it back. The next command that opens the port
says so; ``robocal lerobot restore-previous`` writes it back. Judged by the simulator's state.
"""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path
from typing import Any


def next_run_restores(
    sim: Any, folder: Path, robot: str, before: dict[str, tuple[int, ...]], env: dict[str, str]
) -> list[str]:
    """Run ``robocal lerobot restore-previous`` against the simulator; what it got wrong (empty: all back).

    Args:
        sim: The trial's simulator (``harness._Sim``), the device attached and running again.
        folder: The trial's folder (its working folder).
        robot: The simulated arm.
        before: Every motor's judged registers before the faulty run.
        env: The environment of the faulty run (the same state folder).
    """
    from .harness import _registers, _torque_on

    left = _registers(sim.state())
    changed = sorted(n for n in before if left.get(n) != before[n])
    r = subprocess.run(
        [sys.executable, "-m", "robocal", "lerobot", "restore-previous", "--robot", robot, "--port",
         sim.info["port"]],
        cwd=folder, env=env, stdin=subprocess.DEVNULL, capture_output=True, text=True, timeout=600,
    )  # fmt: skip
    failures = []
    tail = " | ".join(r.stderr.strip().splitlines()[-2:])
    if r.returncode != 0:
        failures.append(f"next run: restore-previous exit {r.returncode} ({tail})")
    if changed and "note: a previous `robocal lerobot calibrate" not in r.stderr:
        failures.append(f"next run did not report what was left changed on {', '.join(changed)} ({tail})")
    state = sim.state()
    still = sorted(n for n, regs in _registers(state).items() if regs != before[n])
    if still:
        failures.append(f"next run left registers changed: {', '.join(still)}")
    if changed and _torque_on(state):
        failures.append(f"torque on after the next run: {', '.join(_torque_on(state))}")
    return failures
