"""After a fault the host could not act on: the next run reports what was left changed and restores it (issue 26).

The run's register snapshot stays in robocal's state folder (each trial has its own ``XDG_STATE_HOME``) when a
SIGKILL, a lost device or a frozen one kept robocal from writing it back. The next command that opens the port
says so; ``robocal lerobot restore-previous`` writes it back. Judged by the simulator's state.

A Damiao zero stored in flash by ``sweep --auto --write-zero`` cannot be written back (it is the position the motor
was at): the next run says which motors have one with no file, and writes the file when it finishes
(:func:`damiao_next_run_reports_zeros`).
"""

from __future__ import annotations

import subprocess
import sys
import time
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


DAMIAO_ZERO_NOTE = "note: a previous `robocal sweep --auto --write-zero`"
"""The start of the line the next run on a Damiao bus prints when a killed ``--write-zero`` run left zeros in flash."""


def damiao_next_run_reports_zeros(
    sim: Any, folder: Path, args: list[str], env: dict[str, str], zeroed: list[str]
) -> list[str]:
    """After a ``--write-zero`` run the host lost with zeros in flash and no file: run it again; what it got wrong.

    The next run (the same command, the next step the note names) must say in its one ``note:`` line which motors
    have a new zero in flash (``zeroed``: judged from the simulator, one flash write each), leave no motor enabled,
    and, when it finishes (its file written), leave no record of them in the state folder.

    Args:
        sim: The trial's simulator (``harness._Sim``), running again.
        folder: The trial's folder (its working folder; the state folder is ``folder/state``).
        args: The faulty run's robocal arguments.
        env: Its environment (the same ``XDG_STATE_HOME``).
        zeroed: The motors whose zero changed.

    The caller puts a relay on the faulty run's port first: the record is kept per bus, by its address.
    """
    r = subprocess.run(
        [sys.executable, "-m", "robocal", *args], cwd=folder, env=env, stdin=subprocess.DEVNULL,
        capture_output=True, text=True, timeout=600,
    )  # fmt: skip
    failures = []
    tail = " | ".join(r.stderr.strip().splitlines()[-2:])
    if r.returncode == 70 or "Traceback" in r.stderr:
        failures.append(f"next run: exit {r.returncode} / traceback ({tail})")
    notes = [ln for ln in r.stderr.splitlines() if ln.startswith(DAMIAO_ZERO_NOTE)]
    if len(notes) != 1 or any(m not in notes[0] for m in zeroed) or "wrote no calibration file" not in notes[0]:
        failures.append(f"next run did not say the zeros of {', '.join(zeroed)} are in flash with no file ({tail})")
    deadline = time.monotonic() + 30.0  # its TIMEOUT (0.5 s) stops a motor it could not make limp
    while (on := [j["name"] for j in sim.state() if j["enabled"]]) and time.monotonic() < deadline:
        time.sleep(0.05)
    if on:
        failures.append(f"enabled after the next run: {', '.join(on)}")
    out = folder / "cal" / "calibration.json"
    kept = sorted((folder / "state" / "robocal" / "left-changed").glob("*.json"))
    if r.returncode in (0, 1) and out.exists() and kept:
        failures.append(f"next run wrote its file but left the record {kept[0].name}")
    return failures
