"""The simulated OpenArm's hands, read as fast as a client can: the joint follows the hand, whatever the read rate.

A paced sweep places each joint only after a client read the last placement. A limp joint under gravity drifts a
little between two placements; the hand used to give the joint the speed from that drifted position to the next
placement over the few milliseconds between them, which carried it further by the next one: read every few ms
(``robocal sweep --source can:socketcand:...`` refreshing all eight motors against ``robocal sim openarm``) the
joint flew from stop to stop and the sweep saw spans of 3-137 rad (span_mismatch on every joint). Judged by the
readings against the simulator's stops.
"""

from __future__ import annotations

import math
import time

import pytest

pytest.importorskip("can")

from robocal.backends.damiao.bus import DamiaoBus
from robocal.backends.damiao.openarm import SimOpenArm
from robocal.backends.damiao.openarm_hands import OpenArmHands
from robocal.backends.damiao.openarm_urdf import openarm_urdf_joint
from robocal.backends.sim.operator import HandOperator

pytestmark = pytest.mark.timeout(120)


@pytest.mark.parametrize("joint", ["joint_2", "joint_4"])  # the two joints gravity loads most
def test_a_paced_sweep_read_flat_out_stays_between_the_stops(joint: str) -> None:
    arm = SimOpenArm(f"robocal-hands-pace-{joint}-{time.monotonic_ns()}", side="right", seed=5, realtime=True).start()
    operator = HandOperator(OpenArmHands([arm]))
    spec = next(j for j in arm.joints if j.name == joint)
    try:
        with DamiaoBus(arm.channel, arm.motor_specs(), interface="virtual", timeout_s=1.0) as bus:
            bus.disable()
            readings: list[float] = []
            truth: list[float] = []
            operator.sweep([openarm_urdf_joint("right", joint)], seconds=2.0, dwell_s=0.2, paced=True)
            deadline = time.monotonic() + 60
            while operator.busy and time.monotonic() < deadline:
                bus.refresh()  # every motor, no pause: the rate that made the joint fly
                readings.append(bus.refresh([joint])[joint].position_rad)
                truth.append(arm.joint_rad(joint))
            finished = not operator.busy
    finally:
        operator.close()
        arm.stop()
    assert finished, "the paced sweep did not finish"
    lo, hi = spec.stop_lower_rad, spec.stop_upper_rad
    margin = math.radians(3.0)
    assert lo - margin <= min(truth) and max(truth) <= hi + margin, (min(truth), max(truth), lo, hi)
    # both stops reached (the hand pressed it into each), the span read as the stops' within 3°
    assert min(truth) < lo + margin and max(truth) > hi - margin
    span = max(readings) - min(readings)
    assert span == pytest.approx(hi - lo, abs=math.radians(3.0)), (span, hi - lo)
