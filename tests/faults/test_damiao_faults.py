"""Fault injection on the Damiao path (issue 31; the oracle of issue 26 item 5, ``damiao_harness.py``).

``sweep --auto --robot openarm_follower_right`` against ``robocal sim openarm`` (its own process, socketcand), the
gripper's stop search, one fault at a random instant of a phase; judged by the simulated motors' state: none
enabled, every RAM register as before (TIMEOUT excepted only where robocal could not act), flash and zero
untouched, the exit code. Each trial takes 15-40 s (``slow``); ``-k quick`` picks the seeded quick set
(``ROBOCAL_FAULT_TRIALS=more`` adds seven, about 4 minutes); the soak
(``python benchmarks/run.py faults --robots openarm --trials N``) runs more. The oracle itself is checked first,
fast: a motor left enabled and a register left changed are both seen.
"""

from __future__ import annotations

import os
import random
from pathlib import Path

import pytest

pytest.importorskip("can")

from .damiao_harness import ZERO_PHASE, _judge, _motors, run_openarm_trial
from .harness import TrialResult, _Sim

pytestmark = pytest.mark.timeout(900)


class _Ended:
    """A finished robocal run for the oracle: no output."""

    def __init__(self) -> None:
        self.lines: list[str] = []


def test_the_oracle_sees_a_motor_left_enabled_and_a_register_left_changed(tmp_path: Path) -> None:
    from robocal.backends.damiao.bus import DamiaoBus, DamiaoMotor
    from robocal.backends.damiao.tables import Register

    sim = _Sim("openarm", tmp_path, argv=("--side", "right", "--port", "0"))
    try:
        before = _motors(sim.state())
        host, port = sim.info["socketcand"].rsplit(":", 1)
        grip = DamiaoMotor("openarm_right_gripper_motor", 0x08, 0x18, "DM4310")
        bus = DamiaoBus(
            "can0",
            [grip],
            interface="socketcand",
            allow_motion=True,
            bus_kwargs={"host": host, "port": int(port)},
        )
        try:
            bus.write_register(grip.name, Register.KP_ASR, 0.125)
            bus.enable([grip.name])
        finally:
            bus.close()  # no limp, no write-back: what a careless host leaves
        (tmp_path / "cal").mkdir()
        run = _Ended()
        failures = _judge(sim, tmp_path, "sigint", 130, before, run)  # type: ignore[arg-type]
        assert failures == [
            "enabled after the run: openarm_right_gripper_motor",
            "openarm_right_gripper_motor: RAM register(s) changed: KP_ASR",
        ]
        assert _motors(sim.state())["openarm_right_gripper_motor"]["ram"]["KP_ASR"] == 0.125
    finally:
        sim.stop()


def _case(fault: str, phase: str, kind: str = "more") -> object:
    return pytest.param(fault, phase, marks=pytest.mark.slow, id=f"{kind}-openarm-{fault}-{phase}")


QUICK = [
    _case("sigint", "search", "quick"),
    _case("sigkill", "contact", "quick"),  # only the TIMEOUT watchdog can make the motor limp
    _case("lost-bus", "search", "quick"),  # the socketcand connection cut
]
MORE = [
    _case("sigterm", "contact"),
    _case("sighup", "search"),
    _case("double-sigint", "contact"),
    _case("lost-device", "contact"),
    _case("frozen-device", "search"),
    _case("cpu-stall", "search"),
    _case("sigint", "file-write"),
]


ZERO = [  # --write-zero: a signal right after the first zero went to flash (before: 'nothing was written' with
    # every motor's zero changed and no file; now the file is written first and the signal ends the run after it)
    pytest.param(fault, marks=pytest.mark.slow, id=f"{kind}-openarm-zero-{fault}-zero-write")
    for fault, kind in (("sigint", "quick"), ("sigterm", "more"), ("sighup", "more"))
]
SEEDED = QUICK + MORE if os.environ.get("ROBOCAL_FAULT_TRIALS") == "more" else QUICK


def _reached(fault: str, phase: str, key: str, write_zero: bool = False) -> TrialResult:
    """A trial that reached its phase: up to three seeds. On a loaded machine the search itself may end first
    (a watchdog tripped by a late frame, a reply late at start-up: exit 3, every motor limp), which is no verdict."""
    for attempt in range(3):
        rng = random.Random(sum(map(ord, key)) + 1000 * attempt)
        result = run_openarm_trial(fault, phase, rng, write_zero=write_zero)
        if result.injected:
            return result
    pytest.skip(
        f"three runs ended on their own before the {phase} phase (the machine's load; last: {result.failures})"
    )


@pytest.mark.parametrize(("fault", "phase"), SEEDED)
def test_fault_on_the_damiao_path_leaves_every_motor_limp_and_restored(fault: str, phase: str) -> None:
    result = _reached(fault, phase, f"openarm/{fault}/{phase}")
    assert result.injected, f"the run ended before the {phase} phase (exit {result.exit_code})"
    assert result.failures == (), (
        f"exit {result.exit_code}: {'; '.join(result.failures)} [{result.stderr_tail}]"
    )
    expected = {"sigint": 130, "double-sigint": 130, "sigterm": 143, "sighup": 129, "sigkill": -9, "lost-bus": 3,
                "lost-device": 3, "frozen-device": 3}  # fmt: skip
    if phase in ("search", "contact") and fault in expected:
        assert result.exit_code == expected[fault]


@pytest.mark.parametrize("fault", ZERO if os.environ.get("ROBOCAL_FAULT_TRIALS") == "more" else ZERO[:1])
def test_a_signal_while_zeros_go_to_flash_ends_after_the_file_is_written(fault: str) -> None:
    result = _reached(fault, ZERO_PHASE, f"openarm-zero/{fault}", write_zero=True)
    assert result.injected, f"the run ended before a zero was stored (exit {result.exit_code})"
    assert result.failures == (), (
        f"exit {result.exit_code}: {'; '.join(result.failures)} [{result.stderr_tail}]"
    )
    assert result.exit_code == {"sigint": 130, "sigterm": 143, "sighup": 129}[fault]
    assert "after writing" in result.stderr_tail and "(complete)" in result.stderr_tail
