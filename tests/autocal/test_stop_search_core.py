"""The core stop search against a synthetic 1-DOF plant (spring-damper stops, friction, gravity, PD drive)."""

from __future__ import annotations

import math

import pytest

from robocal.core.stop_search import Command, SearchConfig, StopSample, StopSearch, joint_zero
from robocal.errors import InvalidCalibrationError

from .plant import Plant, run_search

CAP = 1.5
KP = 10.0


def config(**kw: object) -> SearchConfig:
    base: dict[str, object] = {
        "speed_rad_s": math.radians(10),
        "torque_cap_nm": CAP,
        "max_travel_rad": 1.0 + math.radians(15),
        "max_time_s": 1.0 / math.radians(10) + 6.0,
        "max_lag_rad": CAP / KP,
    }
    base.update(kw)
    return SearchConfig(**base)  # type: ignore[arg-type]


def search(plant: Plant, direction: int, **kw: object) -> tuple[StopSearch, list[Command]]:
    s = StopSearch(direction, config(**kw))
    cmds = run_search(plant, s)
    assert s.done
    return s, cmds


@pytest.mark.parametrize("k", [100.0, 300.0, 1000.0])
def test_stiff_stop_found_and_corrected(k: float) -> None:
    plant = Plant(k_hi=k, k_lo=k, seed=1)
    s, cmds = search(plant, +1)
    r = s.result
    assert r.code == "ok", r.reason
    assert r.test in ("torque", "lag")
    # the pressed position sinks by ~cap/k; the corrected surface is within 0.3° of the true stop
    assert r.q_pressed_rad - 1.0 == pytest.approx(CAP / k, abs=0.3 * CAP / k + math.radians(0.1))
    assert abs(r.q_stop_rad - 1.0) < math.radians(0.3)
    if k <= 300:  # a 1000 N·m/rad stop sinks 0.04° between the press levels: below one encoder tick
        assert r.stiffness_nm_per_rad == pytest.approx(k, rel=0.35)
    assert cmds[-1].action == "hold"
    assert plant.peak <= 1.1 * CAP
    # backed off ~5° from the stop
    assert 1.0 - plant.q == pytest.approx(math.radians(5), abs=math.radians(1.5))


def test_two_sided_zero_and_span_with_asymmetric_stops() -> None:
    plant = Plant(q_lo=-0.95, q_hi=1.1, k_lo=150, k_hi=600, seed=2)
    lo, _ = search(plant, -1)
    hi, _ = search(plant, +1, max_travel_rad=2.5, max_time_s=20.0)
    j = joint_zero("j", lo.result, hi.result, -1.0, 1.0)
    assert j.code == "ok"
    # raw midpoint 0.075 maps onto the expected midpoint 0 → offset 0.075; span 2.05 within tolerance of 2
    assert j.offset_rad == pytest.approx(0.075, abs=math.radians(0.3))
    assert j.span_rad == pytest.approx(2.05, abs=math.radians(0.5))


def test_missing_stop_aborts_within_travel_bound_and_goes_limp() -> None:
    plant = Plant(missing_hi=True, seed=3)
    s, cmds = search(plant, +1)
    r = s.result
    assert r.code == "missing_stop"
    assert cmds[-1].action == "limp"
    assert r.travel_rad <= config().max_travel_rad + math.radians(1)
    assert r.duration_s <= config().max_travel_rad / math.radians(10) + 2.0
    assert "travel bound" in r.reason


def test_time_bound() -> None:
    plant = Plant(missing_hi=True, seed=3)
    s, _ = search(plant, +1, max_time_s=2.0, max_travel_rad=3.0)
    assert s.result.code == "timeout"
    assert s.result.duration_s == pytest.approx(2.0, abs=0.02)


def test_stiction_at_0_8_of_cap_is_no_false_stop() -> None:
    plant = Plant(stiction=0.8 * CAP, coulomb=0.3, seed=4)
    s, _ = search(plant, +1)
    assert s.result.code == "ok"
    assert abs(s.result.q_stop_rad - 1.0) < math.radians(0.5)


def test_unarmed_detector_ignores_a_stall_at_the_start() -> None:
    # the joint starts 1° from the stop: never reaches the minimum travel → no stop declared; held at the
    # full push for 2 dwells it is reported blocked (not a stop), and left limp
    plant = Plant(q=1.0 - math.radians(1), seed=5)
    s, cmds = search(plant, +1, max_time_s=3.0)
    assert s.result.code == "blocked"
    assert math.isnan(s.result.q_stop_rad)
    assert s.result.q_pressed_rad == pytest.approx(1.0, abs=math.radians(1))
    assert "before the stall test could arm" in s.result.reason
    assert cmds[-1].action == "limp"


def test_stiction_at_start_is_not_blocked() -> None:
    # breakaway at 0.8× the cap builds 0.8× the push: below the 0.9 thresholds, so the joint is not "blocked"
    plant = Plant(stiction=0.8 * CAP, coulomb=0.2, seed=12)
    s, _ = search(plant, -1)
    assert s.result.code == "ok"


def test_obstacle_is_a_span_mismatch() -> None:
    plant = Plant(obstacle=0.2, seed=6)
    lo, _ = search(plant, -1)
    hi, _ = search(plant, +1, max_travel_rad=2.5, max_time_s=20.0)
    assert lo.result.ok and hi.result.ok
    j = joint_zero("j", lo.result, hi.result, -1.0, 1.0)
    assert j.code == "span_mismatch"
    assert math.isnan(j.offset_rad)
    assert "differs from the expected 114.6°" in j.reason


def test_overload_latch_recovered_by_reread() -> None:
    plant = Plant(overload_torque=0.85 * CAP, overload_time_s=0.1, seed=7)
    s, _ = search(plant, +1)
    r = s.result
    assert r.code == "ok", r.reason
    assert r.test == "overload+reread"  # the latch (0.1 s) trips before the stall test's dwell (0.2 s)
    assert abs(r.q_stop_rad - 1.0) < math.radians(1.0)


def test_lost_replies_at_the_stop_confirmed_by_reread() -> None:
    plant = Plant(silent_beyond=1.0, seed=8)
    s, _ = search(plant, +1)
    r = s.result
    assert r.code == "ok", r.reason
    assert r.test == "no-reply+reread"
    assert abs(r.q_stop_rad - 1.0) < math.radians(1.0)


@pytest.mark.slow
def test_gravity_loaded_soft_stop_corrected() -> None:
    g = lambda q: 0.3  # noqa: E731
    truth = []
    for corrected in (False, True):
        lo_p = Plant(k_lo=15, k_hi=15, gravity=g, seed=9)
        kw = {"gravity_nm": g} if corrected else {}
        lo, _ = search(lo_p, -1, **kw)
        hi, _ = search(lo_p, +1, max_travel_rad=2.5, max_time_s=20.0, **kw)
        j = joint_zero("j", lo.result, hi.result, -1.0, 1.0)
        assert j.code == "ok"
        truth.append(j.offset_rad)
    # without the gravity model the zero is off by ≈ τ_g/k = 0.02 rad; with it, within 0.3°
    assert abs(truth[0]) > math.radians(0.6)
    assert abs(truth[1]) < math.radians(0.3)


def test_second_touch_agrees() -> None:
    plant = Plant(seed=10)
    s, _ = search(plant, +1, second_touch=True)
    r = s.result
    assert r.code == "ok"
    assert len(r.touches) == 2
    assert abs(r.touches[0] - r.touches[1]) < math.radians(0.5)


def test_one_sided_zero_uses_profile_angle() -> None:
    plant = Plant(q_hi=1.2, seed=11)
    s, _ = search(plant, +1, max_travel_rad=1.5)
    j = joint_zero("j", None, s.result, None, math.radians(56.25))
    assert j.offset_rad == pytest.approx(1.2 - math.radians(56.25), abs=math.radians(0.3))


def test_no_reply_at_start_fails() -> None:
    s = StopSearch(1, config())
    assert s.start(StopSample(0.0, math.nan, ok=False)).action == "limp"
    assert s.result.code == "no_reply"


def test_abort() -> None:
    s = StopSearch(1, config())
    s.start(StopSample(0.0, 0.0, 0.0, 0.0))
    assert s.abort().code == "aborted"
    assert s.step(StopSample(0.01, 0.0, 0.0, 0.0)).action == "limp"


@pytest.mark.parametrize("bad", [{"speed_rad_s": 0.0}, {"torque_cap_nm": math.nan}, {"dwell_s": -1.0}])
def test_bad_config(bad: dict[str, float]) -> None:
    with pytest.raises(InvalidCalibrationError, match="must be a positive finite number"):
        config(**bad)


def test_gravity_in_the_joint_frame_corrects_the_zero_with_an_unknown_offset() -> None:
    """A URDF gravity model is known in the joint frame; the driver frame is ``s = q + z`` with z unknown."""
    from robocal.core.gravity import JointGravity

    z = 0.4  # the zero to find: the stops in the driver frame are at −1 + z and 1 + z
    g_joint = JointGravity("j", 0.25, 0.15)  # τ_g(q) = 0.25 cos q + 0.15 sin q  (joint frame)
    plant = Plant(q_lo=-1.0 + z, q_hi=1.0 + z, k_lo=15, k_hi=15, gravity=lambda s: g_joint(s - z), seed=12, q=z)
    lo, _ = search(plant, -1)
    hi, _ = search(plant, +1, max_travel_rad=2.5, max_time_s=20.0)
    plain = joint_zero("j", lo.result, hi.result, -1.0, 1.0)
    fixed = joint_zero("j", lo.result, hi.result, -1.0, 1.0, gravity=g_joint)
    # uncorrected: the midpoint moves by ≈ ½(τ_g(−1) + τ_g(1))/k = ½·2·0.25·cos(1)/15 ≈ 0.0090 rad (0.5°)
    assert plain.offset_rad - z == pytest.approx(0.25 * math.cos(1.0) / 15, abs=math.radians(0.15))
    assert abs(fixed.offset_rad - z) < math.radians(0.15)
    # each stop moved by its own τ_g(q_joint)/k̂ (k̂ from the press), the span too
    for res, res0, q_joint in ((fixed.lower, lo.result, -1.0), (fixed.upper, hi.result, 1.0)):
        assert res is not None
        shift = res0.q_stop_rad - res.q_stop_rad
        assert shift == pytest.approx(g_joint(q_joint) / res0.stiffness_nm_per_rad, abs=1.5e-4)
    assert abs(fixed.span_rad - 2.0) < abs(plain.span_rad - 2.0) + 1e-9


def test_gravity_correction_of_a_one_sided_stop_and_without_stiffness() -> None:
    from robocal.core.stop_types import StopResult
    from robocal.core.stop_zero import gravity_corrected

    up = StopResult(1, "ok", q_stop_rad=1.5, stiffness_nm_per_rad=50.0)
    j = joint_zero("j", None, up, None, 1.0, gravity=lambda q: 2.0 * q)
    # one-sided: the stop is at its profile angle 1.0 in the joint frame: τ_g = 2 N·m, sink 0.04 rad
    assert j.offset_rad == pytest.approx(1.5 - 0.04 - 1.0)
    assert j.upper is not None and j.upper.q_stop_rad == pytest.approx(1.46)
    # no stiffness estimate (a transit stall): nothing to divide by, left as measured
    stalled = StopResult(1, "ok", q_stop_rad=1.5, test="transit-stall")
    assert gravity_corrected(None, stalled, None, 1.0, lambda q: 2.0) == (None, stalled)
