"""The Koch follower end to end on the Dynamixel firmware simulation: its full-turn joints have no hard stop, so
the profile marks them ``stops: none`` and they are reported ``not_searched`` (never moved, calibration kept)."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from robocal.workflows.lerobot import robot_spec
from robocal.workflows.lerobot.auto import AutoCalibrationRequest, auto_calibrate, auto_section
from robocal.workflows.lerobot.auto_sim import open_auto_arm

pytestmark = pytest.mark.timeout(600)

INPROC = "sim?transport=inproc"
"""The simulated arm behind an in-process port: the pty's packets (test_lerobot_auto_inproc), no polling."""

FULL_TURN = ("shoulder_pan", "wrist_roll")


def test_koch_profile_marks_the_full_turn_joints() -> None:
    section = auto_section("koch_follower")
    none = [j for j in section.joints if not j.searched]
    assert [j.name for j in none] == list(FULL_TURN)
    assert all("full-turn" in j.reason for j in none)
    assert set(robot_spec("koch_follower").full_turn) == set(FULL_TURN)  # the same joints LeRobot treats so


@pytest.mark.slow
def test_koch_auto_calibration_with_full_turn_joints_not_searched(tmp_path: Path) -> None:
    # a subset: the joints without a pose of their own; the full-turn ones (never moved) cannot be named
    # (tests/autocal/test_autocal_contract.py) and keep their EEPROM calibration
    joints = ["shoulder_lift", "gripper"]
    spec = robot_spec("koch_follower")
    section = auto_section("koch_follower")
    out = tmp_path / "koch.json"
    asked: list[tuple[str, ...]] = []

    def confirm(joints: object, caps: object) -> bool:
        asked.append(tuple(joints))  # type: ignore[arg-type]
        return True

    with open_auto_arm(spec, INPROC, section) as arm:
        eeprom_before = arm.sim.eeprom()
        start = {n: arm.plants[n].q_rad for n in FULL_TURN}  # type: ignore[index]
        res = auto_calibrate(
            arm.bus,
            AutoCalibrationRequest(
                spec,
                section,
                path=out,
                joints=joints,
            ),
            clock=arm.clock,
            confirm_start=confirm,
        )
        eeprom_after = arm.sim.eeprom()
        recovered = arm.sim.recovered_stops(res.calibration)
        truth = dict(arm.sim.truth)
        moved = {n: abs(arm.plants[n].q_rad - start[n]) for n in FULL_TURN}  # type: ignore[index]
        torque = {m.name: arm.sim.servo(m.name).get_reg("Torque_Enable") for m in spec.motors}
    assert asked == [("shoulder_lift", "gripper")]  # only the joints that move
    codes = {o.name: o.stops.code for o in res.auto.joints}
    assert codes == {"shoulder_lift": "ok", "gripper": "ok"}
    assert res.exit_code == 0 and res.auto.failed == ()
    assert set(res.kept) == {*FULL_TURN, "elbow_flex", "wrist_flex"}  # not searched or not selected
    for n in FULL_TURN:
        assert moved[n] < 1e-9  # never driven
        assert eeprom_after[n] == eeprom_before[n]  # their calibration untouched
    for n in ("shoulder_lift", "gripper"):
        lo, hi = recovered[n]
        assert abs(lo - truth[n].stop_low_ticks) <= 3 and abs(hi - truth[n].stop_high_ticks) <= 3
    assert set(torque.values()) == {0}  # every motor limp at the end
    written = json.loads(out.read_text())
    assert list(written) == list(spec.motor_names)


@pytest.mark.slow
def test_whole_koch_auto_calibration_finishes(tmp_path: Path) -> None:
    # LeRobot's KochFollower.configure() gains on elbow_flex (P 1500, I 0, D 600): with the XL330's default gain
    # the elbow, capped at 25 % of 0.52 N·m, stopped 1.8° short of its pose angle (shoulder_lift 0) when it had
    # to hold it for wrist_flex's search, and the run aborted
    spec = robot_spec("koch_follower")
    section = auto_section("koch_follower")
    with open_auto_arm(spec, INPROC, section) as arm:
        gains_before = arm.sim.servo("elbow_flex").get_reg("Position_P_Gain")
        eeprom_before = arm.sim.eeprom()
        res = auto_calibrate(
            arm.bus,
            AutoCalibrationRequest(
                spec,
                section,
                path=tmp_path / "koch.json",
            ),
            clock=arm.clock,
        )
        recovered = arm.sim.recovered_stops(res.calibration)
        truth = dict(arm.sim.truth)
        elbow = arm.sim.servo("elbow_flex")
        gains_after = (elbow.get_reg("Position_P_Gain"), elbow.get_reg("Position_D_Gain"))
        eeprom_after = arm.sim.eeprom()
        torque = {m.name: arm.sim.servo(m.name).get_reg("Torque_Enable") for m in spec.motors}
    codes = {o.name: o.stops.code for o in res.auto.joints}
    assert codes == {
        "shoulder_lift": "ok",
        "elbow_flex": "ok",
        "wrist_flex": "ok",
        "gripper": "ok",
        "shoulder_pan": "not_searched",
        "wrist_roll": "not_searched",
    }
    assert res.exit_code == 0 and set(res.kept) == set(FULL_TURN)
    for n in ("shoulder_lift", "elbow_flex", "wrist_flex", "gripper"):
        lo, hi = recovered[n]
        assert abs(lo - truth[n].stop_low_ticks) <= 3 and abs(hi - truth[n].stop_high_ticks) <= 3, n
    assert gains_after == (gains_before, 0)  # the search's gains written back (RAM as it was)
    for n in FULL_TURN:
        assert eeprom_after[n] == eeprom_before[n]
    assert set(torque.values()) == {0}
    assert res.auto.total_time_s < 60.0  # measured 50.5 s simulated
