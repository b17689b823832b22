"""Issue 11 acceptance of the SO-101 (Feetech firmware) and the Koch (Dynamixel firmware) behind the real SDKs.

The same harness and thresholds as ``python benchmarks/run.py autocal_servo``: every scenario, 2 seeds (seed →
joint, cycling through the profile's order), each a ``lerobot calibrate --auto`` run of one joint with the
unmodified scservo_sdk / dynamixel_sdk over the simulator's in-process port. One search also runs over the
pseudo-terminal: the same packets byte for byte and the same result to the tick.
"""

from __future__ import annotations

import pytest

from .bench_loader import load_benchmark

pytestmark = pytest.mark.timeout(900)


bench = load_benchmark("bench_autocal_servo")
SCENARIOS = {s.name: s for s in bench.SERVO_SCENARIOS}


@pytest.mark.parametrize(
    ("robot", "spec"),
    [
        # one scenario in the fast tier (`-m "not slow"`); every scenario on both firmwares in the full suite
        pytest.param(
            robot,
            spec,
            id=f"{robot}-{spec.name}",
            marks=() if (robot, spec.name) == ("so101_follower", "cable_snag") else pytest.mark.slow,
        )
        for robot in ("so101_follower", "koch_follower")
        for spec in bench.SERVO_SCENARIOS
    ],
)
def test_scenario_meets_acceptance_on_the_servo_firmware(robot: str, spec: object) -> None:
    stats = bench.run_scenario(robot, spec, range(2))
    assert stats.problems() == []
    summary = stats.summary()
    assert summary["n"] == 2
    assert summary["peak_over_cap"] <= 1.10
    assert len({r.joint for r in stats.runs}) == 2  # two different joints


@pytest.mark.slow
@pytest.mark.parametrize(
    ("robot", "scenario", "seed"),
    [("so101_follower", "stiff_100", 4), ("koch_follower", "overload_latch", 1)],
)
def test_the_pty_and_the_in_process_port_carry_the_same_search(robot: str, scenario: str, seed: int) -> None:
    runs, logs = {}, {}
    for transport in ("pty", "inproc"):
        logs[transport] = []
        runs[transport] = bench.run_one(
            robot,
            SCENARIOS[scenario],
            seed,
            transport=transport,
            packet_log=logs[transport],
            packet_timeout_ms=5000.0,  # a loaded machine must not make the pty's SDK retry (one more packet)
        )
    assert runs["pty"].code == "ok"
    assert runs["inproc"] == runs["pty"]  # zero and span errors, times, tests fired, peak torque: identical
    assert len(logs["pty"]) > 1000
    assert logs["inproc"] == logs["pty"]  # every instruction and status packet, byte for byte
