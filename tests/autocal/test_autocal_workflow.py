"""The auto-calibration workflow on drivers over the synthetic plant: order, poses, failures, limp on Ctrl-C."""

from __future__ import annotations

import math

import pytest

from robocal.core.profile_auto import AutoJoint, AutoSection
from robocal.errors import UsageError
from robocal.workflows.autocal.job import AutoCalAbortedError, AutoCalRequest, run_autocal, select_joints

from .plant import Plant, PlantDriver


def joint(name: str, **kw: object) -> AutoJoint:
    base: dict[str, object] = {
        "name": name,
        "stops": "both",
        "rated_nm": 6.0,
        "torque_fraction": 0.25,
        "speed_deg_s": 20.0,
        "tolerance_deg": 15.0,
    }
    base.update(kw)
    return AutoJoint(**base)  # type: ignore[arg-type]


SECTION = AutoSection(
    joints=(joint("a"), joint("b", pose=(("a", 10.0),)), joint("c", stops="upper", upper_deg=40.0))
)
LIMITS = {"a": (-1.0, 1.0), "b": (-0.5, 1.5), "c": (-1.0, math.radians(40))}


def drivers(**plants: Plant) -> dict[str, PlantDriver]:
    return {n: PlantDriver(n, p) for n, p in plants.items()}


def default_plants(**over: Plant) -> dict[str, Plant]:
    # true zeros: a +0.1, b −0.2, c +0.05 (s = q + offset)
    plants = {
        "a": Plant(q_lo=-0.9, q_hi=1.1, kp=1.5 / math.radians(3), seed=1),
        "b": Plant(q_lo=-0.7, q_hi=1.3, kp=1.5 / math.radians(3), q=0.3, seed=2),
        "c": Plant(q_lo=-2.0, q_hi=math.radians(40) + 0.05, kp=1.5 / math.radians(3), seed=3),
    }
    plants.update(over)
    return plants


def test_zeros_found_in_order_and_poses_held() -> None:
    d = drivers(**default_plants())
    res = run_autocal(d, AutoCalRequest(SECTION, LIMITS))
    assert [j.name for j in res.joints] == ["a", "b", "c"]
    off = res.offsets_rad
    assert off["a"] == pytest.approx(0.1, abs=math.radians(0.3))
    assert off["b"] == pytest.approx(-0.2, abs=math.radians(0.3))
    assert off["c"] == pytest.approx(0.05, abs=math.radians(0.3))
    assert res["a"].stops.span_rad == pytest.approx(2.0, abs=math.radians(0.5))
    # a moved to its pose angle (10°) before b's search and held it: s = q + offset
    assert d["a"].plant.q == pytest.approx(math.radians(10) + 0.1, abs=math.radians(1.5))
    # b parked mid-range
    assert d["b"].plant.q == pytest.approx(0.3, abs=math.radians(1.5))
    assert res.total_time_s < 60
    rep = res.to_report()["joints"]["a"]
    assert rep["code"] == "ok" and rep["lower"]["test"] in ("torque", "lag")
    assert rep["q_stop_minus_deg"] == pytest.approx(math.degrees(-0.9), abs=0.3)


def test_missing_stop_fails_that_joint_only_and_leaves_it_limp() -> None:
    d = drivers(**default_plants(b=Plant(q_lo=-0.7, missing_hi=True, kp=1.5 / math.radians(3), seed=2)))
    res = run_autocal(d, AutoCalRequest(SECTION, LIMITS))
    assert [j.ok for j in res.joints] == [True, False, True]
    assert res["b"].stops.code == "missing_stop"
    assert "b: missing_stop (upper stop: no stop within the travel bound" in res.failure_summary()
    assert d["b"].is_limp
    assert "b" not in res.offsets_rad


def test_snag_is_a_span_mismatch() -> None:
    d = drivers(
        **default_plants(a=Plant(q_lo=-0.9, q_hi=1.1, obstacle=0.4, kp=1.5 / math.radians(3), seed=1))
    )
    res = run_autocal(d, AutoCalRequest(SECTION, LIMITS, joints=["a"]))
    assert res["a"].stops.code == "span_mismatch"
    assert d["a"].is_limp


def test_ctrl_c_makes_every_motor_limp() -> None:
    d = drivers(**default_plants())
    d["b"].interrupt_after = 50
    with pytest.raises(KeyboardInterrupt):
        run_autocal(d, AutoCalRequest(SECTION, LIMITS))
    assert all(x.limp_count >= 1 for x in d.values())


def test_blocked_pose_move_aborts_limp() -> None:
    # a's pose move for b is blocked by a wall 5° short of the pose angle → aborted, all limp
    plants = default_plants(a=Plant(q_lo=-0.9, q_hi=1.1, kp=1.5 / math.radians(3), seed=1))
    d = drivers(**plants)
    sec = AutoSection(joints=(joint("a", park_deg=-40.0), joint("b", pose=(("a", 80.0),))))
    plants["a"].obstacle = None
    # the pose asks for 80° + offset: beyond the upper stop (1.1 rad = 63°) → cannot reach it
    with pytest.raises(AutoCalAbortedError, match="joint a: could not reach"):
        run_autocal(d, AutoCalRequest(sec, LIMITS))
    assert all(x.is_limp for x in d.values())


def test_select_joints() -> None:
    assert [j.name for j in select_joints(SECTION, ["c", "a"])] == ["a", "c"]
    with pytest.raises(UsageError, match="no auto-calibration entry for zz"):
        select_joints(SECTION, ["zz"])
    with pytest.raises(UsageError, match="no motor for joint"):
        run_autocal({}, AutoCalRequest(SECTION, LIMITS))


def test_joint_without_stops_is_reported_not_searched_and_never_moves() -> None:
    section = AutoSection(
        joints=(
            joint("pan", stops="none", reason="full-turn motor: no hard stop"),
            *SECTION.joints,
        )
    )
    plants = default_plants()
    d = drivers(**plants)  # no driver for "pan": it needs none
    res = run_autocal(d, AutoCalRequest(section, LIMITS))
    assert [j.name for j in res.joints] == ["pan", "a", "b", "c"]
    pan = res["pan"]
    assert pan.stops.code == "not_searched" and pan.stops.reason == "full-turn motor: no hard stop"
    assert not pan.ok and res.failed == () and res.not_searched == (pan,)
    assert "pan" not in res.offsets_rad and res.offsets_rad["a"] == pytest.approx(0.1, abs=math.radians(0.3))
    assert res.to_report()["joints"]["pan"]["code"] == "not_searched"
    assert res.failure_summary() == ""
    # a run of only such joints moves nothing and takes no time
    alone = run_autocal({}, AutoCalRequest(section, LIMITS, joints=["pan"]))
    assert [o.stops.code for o in alone.joints] == ["not_searched"] and alone.total_time_s == 0.0


def test_first_search_blocked_at_the_start_is_judged_by_the_span() -> None:
    # a starts 1° from its lower stop: the search is blocked before its detector can arm. The contact counts;
    # the span check then passes (the real stop) and the zero is within a degree.
    plants = default_plants(
        a=Plant(q_lo=-0.9, q_hi=1.1, kp=1.5 / math.radians(3), q=-0.9 + math.radians(1), seed=1)
    )
    res = run_autocal(drivers(**plants), AutoCalRequest(SECTION, LIMITS, joints=["a"]))
    a = res["a"]
    assert a.ok and a.stops.lower is not None and a.stops.lower.test == "blocked"
    assert a.stops.offset_rad == pytest.approx(0.1, abs=math.radians(1.0))
    # the same start beside an obstacle 40° short of the upper stop: a span mismatch, not "blocked"
    blocked = Plant(
        q_lo=-0.9, q_hi=1.1, obstacle=0.4, kp=1.5 / math.radians(3), q=0.4 - math.radians(1), seed=1
    )
    section = AutoSection(joints=(joint("a", stops="both"),))
    res = run_autocal(drivers(a=blocked), AutoCalRequest(section, {"a": (-1.0, 1.0)}))
    assert res["a"].stops.code == "span_mismatch"
