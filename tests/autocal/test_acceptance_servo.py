"""Issue 11 acceptance of the SO-101 on the Feetech firmware simulation behind the real SDK (seeded subset).

The same harness and thresholds as ``python benchmarks/run.py autocal-servo``: every scenario, 2 seeds (seed →
joint, cycling through the profile's order), each a ``lerobot calibrate --auto`` run of one joint over the
pseudo-terminal with the unmodified scservo_sdk.
"""

from __future__ import annotations

import importlib.util
import sys
from pathlib import Path
from types import ModuleType

import pytest

BENCHMARKS = Path(__file__).resolve().parents[2] / "benchmarks"

pytestmark = pytest.mark.timeout(900)


def _bench() -> ModuleType:
    name = "bench_autocal_servo"
    if name in sys.modules:
        return sys.modules[name]
    spec = importlib.util.spec_from_file_location(name, BENCHMARKS / f"{name}.py")
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    sys.modules[name] = module
    spec.loader.exec_module(module)
    return module


bench = _bench()


@pytest.mark.parametrize("spec", bench.SERVO_SCENARIOS, ids=lambda s: s.name)
def test_so101_scenario_meets_acceptance_on_the_feetech_firmware(spec: object) -> None:
    stats = bench.run_scenario("so101_follower", spec, range(2))
    assert stats.problems() == []
    summary = stats.summary()
    assert summary["n"] == 2
    assert summary["peak_over_cap"] <= 1.10
    assert len({r.joint for r in stats.runs}) == 2  # two different joints
