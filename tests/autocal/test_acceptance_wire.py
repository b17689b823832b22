"""Issue 11 acceptance over the wire on one seed: the harness of ``benchmarks/run.py autocal_wire``."""

from __future__ import annotations

import pytest

from .bench_loader import load_benchmark

pytest.importorskip("can")

bench = load_benchmark("bench_autocal_wire")
SPECS = {spec.name: (spec, fault) for spec, fault in bench.WIRE_SCENARIOS}


def test_the_checked_scenarios_carry_their_faults_and_verdicts() -> None:
    """The three scenarios below are the benchmark's own: their ``sim:lite`` fault option and expected verdict."""
    checked = {
        name: (SPECS[name][1], SPECS[name][0].expect)
        for name in ("stiff_600", "missing_stop", "overload_latch")
    }
    assert checked == {
        "stiff_600": ("", "accurate"),
        "missing_stop": ("missing", "abort"),
        "overload_latch": ("overload", "accurate"),
    }


@pytest.mark.slow
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
