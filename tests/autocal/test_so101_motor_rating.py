"""The SO-101 follower's servo: the profile and the simulated firmware agree on a real follower's STS3215.

The SO-ARM100 bill of materials gives the follower six STS3215 7.4 V servos with 1/345 gear (C001; a 12 V servo is
an option), LeRobot's docs "6x STS3215 motors with 1/345 gearing". Its stall torque at 7.4 V, 19.5 kg·cm = 1.91
N·m, is what the simulated firmware gives and what the profile rates every joint at, so a torque cap in N·m is the
torque the servo applies (``Torque_Limit = 1000·cap/rated``) and the detection torque the report prints is the one
the joint felt. With 2.9 N·m (the 12 V servo) in the profile, the simulated shoulder_lift was capped at 0.57 N·m
while the report said 0.87, and it could not lift the upper arm.
"""

from __future__ import annotations

import math
from typing import Any

import pytest

from robocal.backends.servo_ratings import RATINGS
from robocal.core.stop_search import StopSample
from robocal.formats.profiles import load_profile
from robocal.workflows.lerobot import robot_spec
from robocal.workflows.lerobot.auto import AutoCalibrationRequest, auto_calibrate, auto_section
from robocal.workflows.lerobot.auto_sim import open_auto_arm

pytestmark = pytest.mark.timeout(600)

INPROC = "sim?transport=inproc"
"""The simulated arm behind an in-process port: the pty's packets (test_lerobot_auto_inproc), no polling."""

STS3215_NM = 19.5 * 9.80665 / 100  # 19.5 kg·cm at 7.4 V


def test_profile_rates_every_joint_at_the_simulated_servos_stall_torque() -> None:
    assert RATINGS["sts3215"].stall_torque_nm == pytest.approx(STS3215_NM, abs=0.005)
    profile = load_profile("so101_follower")
    section = profile.auto
    assert section is not None
    assert {j.model for j in profile.joints} == {"sts3215"}
    assert {j.name: j.rated_nm for j in section.joints} == {
        j.name: RATINGS["sts3215"].stall_torque_nm for j in section.joints
    }
    caps = {j.name: round(j.torque_cap_nm, 3) for j in section.joints}
    assert caps == {
        "shoulder_lift": 0.859,  # 45 %: lifts the whole arm (0.68 N·m in its search pose)
        "elbow_flex": 0.764,  # 40 %: the forearm (0.45 N·m)
        "wrist_flex": 0.477,
        "wrist_roll": 0.477,
        "gripper": 0.477,
        "shoulder_pan": 0.477,
    }
    assert section.max_torque_fraction == 0.45


class _PressedTorque:
    """Records the simulated plant's torque and the torque robocal reads while the joint is pressed."""

    def __init__(self, arm: Any, joint: str) -> None:
        self.arm, self.joint = arm, joint
        self.pairs: list[tuple[float, float]] = []

    def joint_start(self, name: str, cap_nm: float, speed_rad_s: float) -> None:
        pass

    def sample(self, name: str, phase: str, side: str, sample: StopSample) -> None:
        if name == self.joint and phase == "press" and sample.ok:
            self.pairs.append((sample.torque_nm, self.arm.plants[name].read().tau_nm))

    def joint_done(self, outcome: Any) -> None:
        pass


@pytest.mark.slow
def test_the_torque_read_is_the_torque_the_simulated_joint_applies() -> None:
    spec = robot_spec("so101_follower")
    section = auto_section("so101_follower")
    with open_auto_arm(spec, INPROC, section) as arm:
        view = _PressedTorque(arm, "gripper")
        res = auto_calibrate(
            arm.bus,
            AutoCalibrationRequest(
                spec,
                section,
                joints=["gripper"],
            ),
            clock=arm.clock,
            view=view,
        )
    cap = section.joint("gripper").torque_cap_nm  # type: ignore[union-attr]
    assert res.auto["gripper"].ok and len(view.pairs) > 10
    for read, applied in view.pairs:
        assert math.copysign(1, read) == math.copysign(1, applied)
        assert abs(read) == pytest.approx(abs(applied), rel=0.1, abs=0.01)
        assert abs(applied) <= 1.1 * cap  # never above the configured cap + 10 %
    detect = res.auto["gripper"].stops.lower.torque_nm  # type: ignore[union-attr]
    assert abs(detect) == pytest.approx(cap, rel=0.1)


@pytest.mark.slow
def test_the_simulated_follower_lifts_its_own_arm(tmp_path: Any) -> None:
    """With the weight of the shipped URDF on shoulder_lift and elbow_flex both are found (was span_mismatch)."""
    spec = robot_spec("so101_follower")
    section = auto_section("so101_follower")
    port = "sim?seed=1&gravity=shoulder_lift,elbow_flex&transport=inproc"  # the pty's packets, no polling
    with open_auto_arm(spec, port, section) as arm:
        res = auto_calibrate(
            arm.bus,
            AutoCalibrationRequest(
                spec,
                section,
                joints=["shoulder_lift", "elbow_flex"],
                path=None,
            ),
            clock=arm.clock,
        )
        recovered = arm.sim.recovered_stops(res.calibration)
        truth = dict(arm.sim.truth)
    assert {o.name: o.stops.code for o in res.auto.joints} == {"shoulder_lift": "ok", "elbow_flex": "ok"}
    for name in ("shoulder_lift", "elbow_flex"):
        lo, hi = recovered[name]
        assert abs(lo - truth[name].stop_low_ticks) <= 3 and abs(hi - truth[name].stop_high_ticks) <= 3, name
