"""Issue 11 acceptance over the wire on one seed: the harness of ``benchmarks/run.py autocal_wire``."""

from __future__ import annotations

import pytest

from .bench_loader import load_benchmark

pytest.importorskip("can")

bench = load_benchmark("bench_autocal_wire")
SPECS = {spec.name: (spec, fault) for spec, fault in bench.WIRE_SCENARIOS}


@pytest.mark.parametrize("name", ["stiff_600", "missing_stop", "overload_latch"])
def test_whole_arm_over_the_wire_meets_acceptance(name: str) -> None:
    spec, fault = SPECS[name]
    stats = bench.run_wire_scenario(spec, fault, range(1))
    assert stats.problems() == []
    summary = stats.summary()
    assert summary["n"] == 14  # every Lite joint, one run each
    if name == "stiff_600":
        assert summary["codes"] == {"ok": 14} and summary["zero_max_deg"] < 0.1
    elif name == "overload_latch":
        # the latch trips at every contact (a type-4 stop with "clear faults" clears it) and each joint's stop
        # is confirmed by the position re-read
        assert summary["codes"] == {"ok": 14} and summary["confirmed"] == 14
    else:
        assert summary["codes"] == {"missing_stop": 14}
        assert summary["abort_max_over_bound_s"] < 0.0  # before the travel bound, not only within + 2 s
        assert summary["limp_after_fail"]
