"""Seeded fault-injection trials against the standalone simulated arms (issue 26 item 5; ``harness.py``).

Each trial calibrates one joint (the arms' gripper with ``lerobot calibrate --auto`` on a ``robocal sim`` arm, the
Lite's left wrist roll with ``sweep --auto`` on ``robocal sim lite`` over CAN) with the simulator in its own process,
injects the fault at a random instant of the phase, and judges by the simulator's state. Every combination is a
plain assertion (the ones main failed before issue 26's guard, watchdogs and standalone Lite physics say so); the
soak (``python benchmarks/run.py faults --trials N``) runs many more. Every trial takes 15-90 s, so all are
``slow``; ``-k quick`` picks the seeded quick set. The suite runs the quick set; ``ROBOCAL_FAULT_TRIALS=more`` adds
the thirteen other seeded combinations, which the soak covers too.
"""

from __future__ import annotations

import os
import random

import pytest

from .harness import run_trial

pytestmark = pytest.mark.timeout(900)

def _case(robot: str, fault: str, phase: str, kind: str = "more") -> object:
    # 20-150 s a trial on a loaded machine: every one is over the fast tier's 2 s
    marks = [pytest.mark.slow]
    return pytest.param(robot, fault, phase, marks=marks, id=f"{kind}-{robot}-{fault}-{phase}")


ATTEMPTS = 3
"""A run whose phase never came is run again (same seed), up to this many times: under heavy load (~27) the SO-101
gripper's search sometimes fails on its own before the restore phase ('could not reach 270.8° within 3.9 s:
blocked?', exit 3): nothing to inject there, and not the guard's doing; the next attempt gets there."""

QUICK = [  # pytest tests/faults -k quick
    # failed on main before the motion guard: one Ctrl-C while searching left no register written back and the
    # torque on (2 of 3 runs at 515e316); SIGTERM while searching could leave a register changed
    _case("so101_follower", "sigint", "search", kind="quick"),
    _case("koch_follower", "sigterm", "search", kind="quick"),
    _case("lite", "sigint", "search", kind="quick"),
]
MORE = (
    [
        _case("so101_follower", fault, phase)
        for fault, phase in [
            ("double-sigint", "contact"),  # before the guard: the second Ctrl-C stopped the EEPROM restore
            ("sigterm", "restore"),  # before the guard: registers left changed (see ATTEMPTS)
            ("sighup", "contact"),
            ("cpu-stall", "contact"),
            ("frozen-device", "search"),
            ("lost-device", "search"),  # before: exit 70, then minutes of reply timeouts
            ("sigkill", "search"),  # Feetech has no watchdog: the oracle accepts the torque left on
        ]
    ]
    + [
        _case("koch_follower", fault, phase)
        for fault, phase in [
            ("sigint", "contact"),
            ("sigkill", "contact"),  # the Dynamixel Bus_Watchdog stops the servo 0.5 s after the last packet
            ("lost-device", "contact"),
        ]
    ]
    + [
        _case("lite", fault, phase)
        for fault, phase in [
            ("sigterm", "contact"),  # needs the standalone Lite's joint physics (it had none before)
            ("sigkill", "search"),  # the Robstride CAN timeout disables the motor 0.5 s after the last frame
            ("frozen-device", "search"),
        ]
    ]
)


SEEDED = QUICK + MORE if os.environ.get("ROBOCAL_FAULT_TRIALS") == "more" else QUICK


@pytest.mark.parametrize(("robot", "fault", "phase"), SEEDED)
def test_fault_leaves_the_arm_limp_and_restored(robot: str, fault: str, phase: str) -> None:
    seed = sum(map(ord, f"{robot}/{fault}/{phase}"))
    tails = []
    for _attempt in range(ATTEMPTS):
        result = run_trial(
            robot, fault, phase, random.Random(seed), joints=None if robot == "lite" else "gripper"
        )
        if result.injected:
            break
        tails.append(f"exit {result.exit_code}: {result.stderr_tail}")
    assert result.injected, f"the run ended before the {phase} phase {ATTEMPTS} times: {tails}"
    assert result.failures == (), f"exit {result.exit_code}: {'; '.join(result.failures)}"


def test_a_soak_log_becomes_the_table() -> None:
    """``results_from_log`` reads the soak's lines (a soak stopped early keeps its counts); a restore-phase trial
    whose search had failed on its own is 'not reached'."""
    from .soak import results_from_log, table

    log = "\n".join(
        [
            "== faults ==",
            "[1/9] so101_follower sigint @ search: pass (exit 130, 12 s) ",
            "[2/9] koch_follower sigkill @ contact: fail (exit -9, 20 s) torque on after the run: gripper [robocal: x]",
            "[3/9] lite sighup @ restore: fail (exit 3, 26 s) exit 3, expected 129 [robocal: j: FAILED span_mismatch: ...]",
            "[4/9] lite sigterm @ file-write: not-reached (exit 3, 17 s) ",
        ]
    )
    results = results_from_log(log)
    assert [(r.robot, r.fault, r.phase, r.verdict, r.exit_code) for r in results] == [
        ("so101_follower", "sigint", "search", "pass", 130),
        ("koch_follower", "sigkill", "contact", "fail", -9),
        ("lite", "sighup", "restore", "not-reached", 3),
        ("lite", "sigterm", "file-write", "not-reached", 3),
    ]
    rows = table(results).splitlines()
    assert rows[0].split() == ["fault", "start-up", "search", "contact", "restore", "file-write", "all", "phases"]
    assert rows[1].split() == ["sigint", "0/0/0", "1/0/0", "0/0/0", "0/0/0", "0/0/0", "1/0/0"]
    assert rows[3].split() == ["sigterm", "0/0/0", "0/0/0", "0/0/0", "0/0/0", "0/0/1", "0/0/1"]
    assert rows[5].split() == ["sigkill", "0/0/0", "0/0/0", "0/1/0", "0/0/0", "0/0/0", "0/1/0"]
    assert rows[-3:] == [
        "koch_follower: 0 pass, 1 fail, 0 not reached",
        "lite: 0 pass, 0 fail, 2 not reached",
        "so101_follower: 1 pass, 0 fail, 0 not reached",
    ]


def test_a_signal_in_python_s_own_start_up_is_not_reached() -> None:
    """Before robocal's first line the signal meets Python's start-up: not robocal's doing (not reached), unless
    the traceback runs through robocal's own files (then robocal's handlers came too late: a failure)."""
    from typing import Any

    from .harness import SRC, _before_robocal, _Run

    def run(err: str) -> Any:
        r = _Run(proc=None)  # type: ignore[arg-type]
        r.lines[:] = err.splitlines(keepends=True)
        return r

    python_s = 'Traceback (most recent call last):\n  File "<frozen runpy>", line 14, in <module>\nKeyboardInterrupt\n'
    assert _before_robocal("sigint", -2, run(python_s))
    assert _before_robocal("double-sigint", -2, run(""))
    assert _before_robocal("sigterm", -15, run(""))
    ours = f'Traceback (most recent call last):\n  File "{SRC}/robocal/cli/__init__.py", line 3\nKeyboardInterrupt\n'
    assert not _before_robocal("double-sigint", -2, run(ours))
    assert not _before_robocal("sigint", 130, run("error: interrupted\n"))
    assert not _before_robocal("sigkill", -9, run(""))
