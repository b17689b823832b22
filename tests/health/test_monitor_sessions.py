"""The live monitor on simulated SO-101 teleoperation (``benchmarks/bench_health_live.py``'s session model).

Issue 30 item 3, done when: a ≥ 2° reading jump or a reading past the stops flagged within 0.1 s, no false alarm
in 10 simulated hours (the benchmark runs the 10 hours per tick; this runs 3 minutes in the fast tier and 1 hour
in the full suite).
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from tests.autocal.bench_loader import load_benchmark

from robocal.health import Monitor

bench = load_benchmark("bench_health_live")
DEG = math.pi / 180


def test_three_minutes_of_teleoperation_raise_no_flag() -> None:
    flags, ticks, _ = bench.hours_without_flags(0.05, chunk_s=90.0, seed=7)
    assert (flags, ticks) == (0, 2 * 90 * 60)


@pytest.mark.slow
def test_an_hour_of_teleoperation_raises_no_flag() -> None:
    flags, ticks, _ = bench.hours_without_flags(1.0, seed=3)
    assert (flags, ticks) == (0, 3600 * 60)


@pytest.mark.parametrize(
    ("jump_deg", "seeds"),
    [
        (2.0, range(8)),
        pytest.param(2.0, range(8, 60), marks=pytest.mark.slow),
        pytest.param(-2.0, range(40), marks=pytest.mark.slow),
        pytest.param(5.0, range(20), marks=pytest.mark.slow),
        pytest.param(17.0, range(20), marks=pytest.mark.slow),
    ],
)
def test_a_jump_in_one_follower_reading_is_flagged_within_a_tenth_of_a_second(
    jump_deg: float, seeds: range
) -> None:
    found, worst_s = bench.detection(seeds, jump_deg)
    assert found == len(seeds)
    assert worst_s <= 1.0 / bench.RATE_HZ + 1e-9  # the tick of the jump, or the next one


def _stop_touch(seed: int) -> tuple[object, int]:
    """A session and a joint whose leader comes within 1° of its upper stop (searched over the seeds)."""
    s = bench.session(seed, 120.0)
    up = np.array(bench.UPPER_DEG) * DEG
    near = s.leader_rad[:, :5] >= up[:5] - 1 * DEG
    joints = np.flatnonzero(near.any(axis=0))
    assert joints.size, f"seed {seed}: no joint reaches its upper stop"
    return s, int(joints[0])


@pytest.mark.parametrize("seed", [1, 2, 3])
def test_a_leader_reading_past_its_stop_is_flagged_on_the_first_tick_past_the_margin(seed: int) -> None:
    s, j = _stop_touch(seed)
    leader = s.leader_rad.copy()
    leader[:, j] += 4 * DEG  # the leader's calibration is 4° off: at its stop it reads 4° past it
    m = Monitor(bench.so101_config(paired=False))
    bench.run_ticks(m, s.t_s, leader, None)
    limit = bench.UPPER_DEG[j] * DEG + 2 * DEG
    first = int(np.flatnonzero(leader[:, j] > limit)[0])
    flags = [f for f in m.history if f.kind == "outside_stops"]
    assert flags[0].joint == bench.JOINTS[j]
    assert flags[0].t_s == s.t_s[first]
    assert {f.joint for f in m.history} == {bench.JOINTS[j]}
    assert {f.kind for f in m.history} == {"outside_stops"}


def test_a_follower_17_degrees_off_is_pinned_at_its_stop_while_the_leader_goes_on() -> None:
    s, j = _stop_touch(1)
    e = -17 * DEG  # the follower reads 17° less than it is: it meets its stop with the leader 17° short
    up = bench.UPPER_DEG[j] * DEG
    true = np.minimum(s.follower_rad[:, j] - e, up)
    follower = s.follower_rad.copy()
    follower[:, j] = true + e
    m = Monitor(bench.so101_config())
    bench.run_ticks(m, s.t_s, follower, s.leader_rad)
    kinds = {(f.joint, f.kind) for f in m.history}
    assert kinds == {(bench.JOINTS[j], "pinned")}
    pinned = [f for f in m.history if f.kind == "pinned"]
    assert all(f.value_rad > 5 * DEG for f in pinned)
    # the first flag: the follower held at up − 17° for 0.3 s while the leader was more than 5° beyond it
    k = int(np.searchsorted(s.t_s, pinned[0].t_s))
    assert follower[k, j] == pytest.approx(up + e, abs=0.5 * DEG)
