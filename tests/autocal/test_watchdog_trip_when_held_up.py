"""A Dynamixel Bus Watchdog that tripped while robocal was held up is never taken for a stop (issue 26 item 4).

robocal arms each searched servo's ``Bus_Watchdog`` (0.5 s). On a busy host robocal can be descheduled for longer,
even between a reply's arrival and the time it stamps the reading, so the gap between two readings may look short
while the servo heard nothing for 0.5 s: it stopped on its own, holds where it was and refuses every goal. The
fault soak lost one Koch trial in five that way (``span_mismatch``, span 0°: the held servo read as the stop). The
driver now checks ``Bus_Watchdog`` after any exchange whose window may hold such a silence, clears and re-arms a
tripped one and carries the command out again: the search goes on and finds the true stops.

All on the simulated clock: "held up" is simulated time passing without a packet.
"""

from __future__ import annotations

import math
from typing import Any

import pytest

from robocal.core.stop_search import Command

pytest.importorskip("dynamixel_sdk")
pytestmark = pytest.mark.timeout(300)


def test_a_tripped_servo_is_cleared_rearmed_and_follows_the_goal_again() -> None:
    from robocal.backends.dynamixel.joint_driver import DynamixelJointDriver
    from robocal.workflows.lerobot import robot_spec
    from robocal.workflows.lerobot.auto import auto_section
    from robocal.workflows.lerobot.auto_sim import open_auto_arm

    spec = robot_spec("koch_follower")
    with open_auto_arm(spec, "sim?transport=inproc", auto_section("koch_follower")) as arm:
        bus, clock, servo = arm.bus, arm.clock, arm.sim.servo("elbow_flex")
        drv = DynamixelJointDriver(bus, "elbow_flex", 3, rated_nm=0.52, cap_nm=0.13, clock=clock)
        drv.configure({}, inverted=False)
        bus.arm_watchdog([3], 0.5)
        s0 = drv.read()
        for _ in range(5):
            s = drv.execute(Command("drive", s0.q_rad, 0.0, 0.13))
        assert servo.watchdog_trips == []
        clock.advance(0.8)  # robocal descheduled for 0.8 s: no packet, the servo's watchdog runs out
        goal = s0.q_rad + math.radians(10.0)
        for _ in range(200):  # bounded: 2 s of simulated time
            s = drv.execute(Command("drive", goal, 0.0, 0.13))
            if abs(s.q_rad - goal) < math.radians(1.0):
                break
        assert len(servo.watchdog_trips) == 1  # it did trip (the next packet found it due)
        assert abs(s.q_rad - goal) < math.radians(1.0)  # the goal was taken: the joint got there
        assert bus.read("Bus_Watchdog", 3) == 25  # armed again, 0.5 s
        assert drv.watchdog_recoveries == 1


def test_a_watchdog_never_armed_is_never_asked() -> None:
    from robocal.backends.dynamixel.joint_driver import DynamixelJointDriver
    from robocal.workflows.lerobot import robot_spec
    from robocal.workflows.lerobot.auto import auto_section
    from robocal.workflows.lerobot.auto_sim import open_auto_arm

    spec = robot_spec("koch_follower")
    with open_auto_arm(spec, "sim?transport=inproc", auto_section("koch_follower")) as arm:
        drv = DynamixelJointDriver(arm.bus, "elbow_flex", 3, rated_nm=0.52, cap_nm=0.13, clock=arm.clock)
        drv.configure({}, inverted=False)
        s0 = drv.read()
        arm.clock.advance(2.0)
        before = arm.sim.bus.instructions
        drv.execute(Command("drive", s0.q_rad, 0.0, 0.13))
        # torque limit, goal, torque on (enable), goal, one block read, Hardware_Error_Status: no Bus_Watchdog read
        assert arm.sim.bus.instructions - before == 6
        assert drv.watchdog_recoveries == 0


@pytest.mark.slow
def test_a_search_held_up_past_the_watchdog_finds_the_true_stops(monkeypatch: pytest.MonkeyPatch) -> None:
    """The soak's case: replies may be late by up to 2 s (``ROBOCAL_REPLY_TIMEOUT_MS`` 2000, as for a simulator in
    another process), and robocal is held up 0.8 s in the middle of the approach to the lower stop."""
    from robocal.workflows.lerobot import robot_spec
    from robocal.workflows.lerobot.auto import AutoCalibrationRequest, auto_calibrate, auto_section
    from robocal.workflows.lerobot.auto_sim import open_auto_arm

    monkeypatch.setenv("ROBOCAL_REPLY_TIMEOUT_MS", "2000")
    spec = robot_spec("koch_follower")
    section = auto_section("koch_follower")
    held: list[float] = []

    class View:
        n = 0

        def joint_start(self, name: str, cap_nm: float, speed_rad_s: float) -> None:
            pass

        def sample(self, name: str, phase: str, side: str, sample: Any) -> None:
            self.n += 1
            if self.n == 40 and phase == "approach":
                held.append(sample.q_rad)
                arm.clock.advance(0.8)  # held up after the reading was stamped, before the next goal went out

        def joint_done(self, outcome: Any) -> None:
            pass

    with open_auto_arm(spec, "sim?seed=1&transport=inproc", section) as arm:
        res = auto_calibrate(
            arm.bus,
            AutoCalibrationRequest(spec, section, joints=["gripper"], path=None),
            clock=arm.clock,
            view=View(),
            confirm_start=lambda names, caps: True,
        )
        servo = arm.sim.servo("gripper")
        assert held and len(servo.watchdog_trips) == 1  # the hold-up did trip the servo
        gripper = res.auto["gripper"]
        assert gripper.ok, gripper.reason
        truth = arm.sim.truth["gripper"]
        true_span_deg = (truth.stop_high_ticks - truth.stop_low_ticks) * 360.0 / 4096
        assert math.degrees(gripper.stops.span_rad) == pytest.approx(true_span_deg, abs=1.0)
