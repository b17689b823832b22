"""Issue 11 acceptance of the SO-101 on the Feetech firmware simulation behind the real SDK (seeded subset).

The same harness and thresholds as ``python benchmarks/run.py autocal-servo``: every scenario, 2 seeds (seed →
joint, cycling through the profile's order), each a ``lerobot calibrate --auto`` run of one joint over the
pseudo-terminal with the unmodified scservo_sdk.
"""

from __future__ import annotations

import pytest

from .bench_loader import load_benchmark

pytestmark = pytest.mark.timeout(900)


bench = load_benchmark("bench_autocal_servo")


@pytest.mark.parametrize("spec", bench.SERVO_SCENARIOS, ids=lambda s: s.name)
def test_so101_scenario_meets_acceptance_on_the_feetech_firmware(spec: object) -> None:
    stats = bench.run_scenario("so101_follower", spec, range(2))
    assert stats.problems() == []
    summary = stats.summary()
    assert summary["n"] == 2
    assert summary["peak_over_cap"] <= 1.10
    assert len({r.joint for r in stats.runs}) == 2  # two different joints
