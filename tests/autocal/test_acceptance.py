"""Issue 11 acceptance on a seeded subset: the same harness and thresholds as ``benchmarks/run.py autocal``."""

from __future__ import annotations

import importlib.util
import sys
from pathlib import Path
from types import ModuleType

import pytest

BENCH = Path(__file__).resolve().parents[2] / "benchmarks" / "bench_autocal.py"


def _bench() -> ModuleType:
    name = "bench_autocal"
    if name in sys.modules:
        return sys.modules[name]
    spec = importlib.util.spec_from_file_location(name, BENCH)
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    sys.modules[name] = module
    spec.loader.exec_module(module)
    return module


bench = _bench()


@pytest.mark.parametrize("robot", ["so101", "lite"])
@pytest.mark.parametrize("spec", bench.SCENARIOS, ids=lambda s: s.name)
def test_scenario_meets_acceptance(robot: str, spec: object) -> None:
    stats = bench.run_scenario(robot, spec, range(2))
    assert stats.problems() == []
    summary = stats.summary()
    assert summary["n"] == 2
    assert summary["peak_over_cap"] <= 1.10


@pytest.mark.parametrize(("robot", "limit"), [("so101", 60.0), ("lite", 180.0)])
def test_whole_robot_time(robot: str, limit: float) -> None:
    assert bench.robot_total_time(robot) < limit
