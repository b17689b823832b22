"""Joints searched at the same time (``alongside``): the profile rules, the lockstep runner, the whole SO-101.

The whole clean SO-101 (``lerobot calibrate --auto``'s workflow through the Feetech SDK on a pseudo-terminal to
the simulated STS3215 firmware) must finish in under 60 s of *simulated* time (issue 11); the clock is the
simulator's, so the bound does not depend on this machine's speed.
"""

from __future__ import annotations

import math
from typing import Any

import pytest

from robocal.core.profile_auto import AutoJoint, AutoSection
from robocal.errors import FileFormatError
from robocal.formats.profiles import parse_profile
from robocal.workflows.autocal.group import run_lockstep
from robocal.workflows.autocal.job import AutoCalRequest, run_autocal
from robocal.workflows.autocal.joint import calibrate_joint, calibrate_joint_steps
from robocal.workflows.lerobot import robot_spec
from robocal.workflows.lerobot.auto import AutoCalibrationRequest, auto_calibrate, auto_section
from robocal.workflows.lerobot.auto_sim import open_auto_arm

from .plant import Plant, PlantDriver

pytestmark = pytest.mark.timeout(600)

INPROC = "sim?transport=inproc"
"""The simulated arm behind an in-process port: the pty's packets (test_lerobot_auto_inproc), no polling."""

KP = 1.5 / math.radians(3)


def _doc(rows: list[dict[str, Any]]) -> dict[str, Any]:
    return {
        "format": "robocal-robot-profile",
        "version": 2,
        "name": "t",
        "joints": [{"name": n, "model": "rs-02"} for n in ("a", "b", "c", "d")],
        "auto_calibration": {"joints": rows},
    }


def test_alongside_groups_follow_the_profile() -> None:
    p = parse_profile(
        _doc(
            [
                {"name": "a"},
                {"name": "b", "pose": {"a": 0}},
                {"name": "c", "alongside": "b", "pose": {"a": 0}},
                {"name": "d", "alongside": "b"},
            ]
        ),
        "t.yaml",
    )
    assert p.auto is not None
    assert [[j.name for j in g] for g in p.auto.groups()] == [["a"], ["b", "c", "d"]]
    assert p.auto.joint("c").alongside == "b"  # type: ignore[union-attr]


@pytest.mark.parametrize(
    ("rows", "message"),
    [
        ([{"name": "a", "alongside": "b"}, {"name": "b"}], "must name a joint earlier"),
        ([{"name": "a"}, {"name": "b", "alongside": 3}], "must name a joint earlier"),
        (
            [{"name": "a", "stops": "none", "reason": "full turn"}, {"name": "b", "alongside": "a"}],
            "not searched",
        ),
        (
            [{"name": "a"}, {"name": "b", "alongside": "a"}, {"name": "c", "alongside": "b"}],
            "itself alongside",
        ),
        ([{"name": "a"}, {"name": "b", "alongside": "a", "pose": {"a": 0}}], "not calibrated before"),
        (
            [
                {"name": "a"},
                {"name": "b", "pose": {"a": 10}},
                {"name": "c", "alongside": "b", "pose": {"a": 0}},
            ],
            "holds it at 10°",
        ),
        ([{"name": "a"}, {"name": "b", "stops": "none", "reason": "x", "alongside": "a"}], "alongside"),
    ],
)
def test_alongside_refusals(rows: list[dict[str, Any]], message: str) -> None:
    with pytest.raises(FileFormatError, match=message):
        parse_profile(_doc(rows), "t.yaml")


def _joint(name: str, **kw: Any) -> AutoJoint:
    return AutoJoint(name, "both", 6.0, 0.25, 20.0, 15.0, **kw)


def _plants() -> dict[str, Plant]:
    return {
        "a": Plant(q_lo=-0.9, q_hi=1.1, kp=KP, seed=1),
        "b": Plant(q_lo=-0.7, q_hi=1.3, kp=KP, q=0.3, seed=2),
    }


def test_lockstep_gives_each_joint_what_it_gets_alone() -> None:
    section = AutoSection(joints=(_joint("a"), _joint("b")))
    alone = {
        n: calibrate_joint(
            PlantDriver(n, p), section.joints[i], section, (-1.0, 1.0), max_lag_rad=math.radians(3)
        )
        for i, (n, p) in enumerate(_plants().items())
    }
    plants = _plants()
    drivers = {n: PlantDriver(n, p) for n, p in plants.items()}
    steps = {
        j.name: calibrate_joint_steps(drivers[j.name], j, section, (-1.0, 1.0), max_lag_rad=math.radians(3))
        for j in section.joints
    }
    together = run_lockstep(drivers, steps, None)
    for n in ("a", "b"):
        assert together[n].ok and together[n].stops.offset_rad == alone[n].stops.offset_rad
        assert together[n].stops.span_rad == alone[n].stops.span_rad
    assert together["a"].stops.offset_rad == pytest.approx(0.1, abs=math.radians(0.3))
    assert together["b"].stops.offset_rad == pytest.approx(0.3, abs=math.radians(0.3))  # stops −0.7..1.3


def test_ctrl_c_in_one_joint_of_a_group_leaves_every_motor_limp() -> None:
    section = AutoSection(joints=(_joint("a"), _joint("b", alongside="a")))
    plants = _plants()
    drivers = {"a": PlantDriver("a", plants["a"]), "b": PlantDriver("b", plants["b"], interrupt_after=50)}
    with pytest.raises(KeyboardInterrupt):
        run_autocal(drivers, AutoCalRequest(section))
    assert drivers["a"].is_limp and drivers["b"].is_limp
    assert 0 < drivers["a"].steps <= 51  # a stopped with b: it was not run to its end first


@pytest.mark.slow
def test_whole_so101_under_60_s_simulated_with_joints_alongside() -> None:
    spec = robot_spec("so101_follower")
    section = auto_section("so101_follower")
    assert [[j.name for j in g] for g in section.groups()][-1] == ["wrist_roll", "gripper", "shoulder_pan"]
    with open_auto_arm(spec, INPROC, section) as arm:
        res = auto_calibrate(arm.bus, AutoCalibrationRequest(spec, section), clock=arm.clock)
        recovered = arm.sim.recovered_stops(res.calibration)
        truth = dict(arm.sim.truth)
    auto = res.auto
    assert auto.failed == () and [o.name for o in auto.joints] == list(section.joint_names)
    assert auto.total_time_s < 60.0
    # the three searched at once: the run is shorter than the joints' times one after the other
    assert sum(o.time_s for o in auto.joints) - auto.total_time_s > 15.0
    for name, (lo, hi) in recovered.items():
        if name in spec.full_turn:
            continue
        t = truth[name]
        shift = 4096 * round((t.stop_low_ticks - lo) / 4096)
        assert abs(lo + shift - t.stop_low_ticks) <= 3 and abs(hi + shift - t.stop_high_ticks) <= 3, name
