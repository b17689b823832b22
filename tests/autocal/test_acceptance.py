"""Issue 11 acceptance on a seeded subset: the same harness and thresholds as ``benchmarks/run.py autocal``."""

from __future__ import annotations

import pytest

from .bench_loader import load_benchmark

bench = load_benchmark("bench_autocal")


@pytest.mark.parametrize("robot", ["so101", "lite"])
@pytest.mark.parametrize("spec", bench.SCENARIOS, ids=lambda s: s.name)
def test_scenario_meets_acceptance(robot: str, spec: object) -> None:
    stats = bench.run_scenario(robot, spec, range(2))
    assert stats.problems() == []
    summary = stats.summary()
    assert summary["n"] == 2
    assert summary["peak_over_cap"] <= 1.10


@pytest.mark.slow
@pytest.mark.parametrize(("robot", "limit"), [("so101", 60.0), ("lite", 180.0)])
def test_whole_robot_time(robot: str, limit: float) -> None:
    assert bench.robot_total_time(robot) < limit


def test_acceptance_problems_names_each_miss_of_an_accurate_scenario() -> None:
    spec = bench.ScenarioSpec("x", bench.Scenario(), zero_tol_deg=0.5, span_tol_deg=1.0)
    good = {
        "n": 2, "codes": {"ok": 2}, "zero_max_deg": 0.4, "span_max_deg": 0.9, "sigma_deg": 0.01,
        "abort_max_over_bound_s": float("nan"), "peak_over_cap": 1.0, "limp_after_fail": True,
    }  # fmt: skip
    assert bench.acceptance_problems(good, spec) == []
    bad = good | {"codes": {"ok": 1, "timeout": 1}, "zero_max_deg": 0.7, "peak_over_cap": 1.5}
    assert bench.acceptance_problems(bad, spec) == [
        "not every run found both stops: {'ok': 1, 'timeout': 1}",
        "zero error 0.700° > 0.5°",
        "peak torque 1.500× the cap",
    ]
    aborting = bench.ScenarioSpec("m", bench.Scenario(), expect="abort")
    assert bench.acceptance_problems(good | {"abort_max_over_bound_s": 0.1}, aborting) == [
        "not every run aborted: {'ok': 2}"
    ]


def test_table_row_prints_the_verdict_and_counts_a_failure(capsys: pytest.CaptureFixture[str]) -> None:
    spec = bench.ScenarioSpec("stiff_1000", bench.Scenario(), stiffness=1000.0)
    stats = bench.ScenarioStats("lite", spec, [bench.RunResult("j", "ok", 0.1, 0.2, peak_over_cap=1.0)] * 2)
    assert bench.print_table_row(stats) == 0
    row = capsys.readouterr().out
    assert row.startswith("stiff_1000") and "ok:2" in row and " 0.100 " in row and row.rstrip().endswith("PASS")
    stats.runs.append(bench.RunResult("j", "timeout", limp_at_end=False))
    assert bench.print_table_row(stats) == 1
    assert "FAIL: not every run found both stops" in capsys.readouterr().out


def test_seeds_per_joint_give_every_joint_that_many_runs(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("AUTOCAL_SEEDS_PER_JOINT", "100")
    seeds, how = bench.robot_seeds("lite")
    assert seeds == range(1400) and how == "100 seeded runs per joint and scenario (14 joints)"
    assert bench.robot_seeds("so101")[0] == range(100 * len(bench.SO101))
    monkeypatch.delenv("AUTOCAL_SEEDS_PER_JOINT")
    monkeypatch.setenv("AUTOCAL_SEEDS", "7")
    assert bench.robot_seeds("lite") == (range(7), "7 seeded runs per scenario (seed → joint, cycling)")
