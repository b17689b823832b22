"""A simulated servo that only holds its pose costs almost nothing per packet, and wakes when anything changes.

The firmware keeps its decoded registers and its :class:`Drive` while the registers do not change; the plant
remembers a resting check that held (:meth:`JointPlant.hold_until`). Whatever changes the registers (a write),
the setpoint or the plant (its parameters) makes the joint move again, as the full integration would.
"""

from __future__ import annotations

import math
from dataclasses import replace

import pytest

from robocal.backends.feetech import FeetechBus
from robocal.backends.sim.physics import JointPlant, PlantParams, SimClock
from robocal.backends.sim.servo import SimServo, SimServoBus

pytestmark = pytest.mark.timeout(120)

TICK = 2 * math.pi / 4096


def test_a_held_joint_is_not_integrated_step_by_step_until_something_changes(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    params = PlantParams(stop_lower_rad=-1.0, stop_upper_rad=1.0, stiction_nm=0.05)
    plant = JointPlant(params, q0_rad=0.2)
    steps = []
    real_step = plant.step
    monkeypatch.setattr(plant, "step", lambda drive: (steps.append(1), real_step(drive))[1])
    clock = SimClock()
    servo = SimServo(1, "sts3215", 2048 + 0.2 / TICK)
    servo.firmware = servo.kind.firmware(servo, plant, clock, zero_ticks=2048)
    with (
        SimServoBus([servo], clock=clock, transport="inproc") as sim,
        FeetechBus(sim.port, {1: "sts3215"}) as bus,
    ):
        start = bus.read("Present_Position", 1)
        bus.write("Torque_Enable", 1, 1)  # holds where it is
        for _ in range(100):
            assert bus.sync_read("Present_Position", [1]) == {1: start}
            clock.sleep(0.01)
        assert bus.sync_read("Present_Position", [1]) == {1: start}
        assert steps == []  # at rest under one drive: never integrated step by step
        assert clock.now() > 1.0 and plant.t_s == pytest.approx(clock.now(), abs=params.dt_s)  # yet on time
        bus.write("Goal_Position", 1, start + 200)  # a write wakes it
        for _ in range(50):
            clock.sleep(0.01)
        assert abs(bus.read("Present_Position", 1) - (start + 200)) <= 3
        assert len(steps) > 100
        steps.clear()
        for _ in range(20):
            bus.sync_read("Present_Position", [1])
            clock.sleep(0.01)
        assert steps == []  # at rest again
        held = bus.read("Present_Position", 1)
        plant.params = replace(params, gravity_nm=0.5, gravity_zero_rad=-1.0)  # new physics: it sags
        for _ in range(50):
            bus.sync_read("Present_Position", [1])
            clock.sleep(0.01)
        assert steps and bus.read("Present_Position", 1) != held
