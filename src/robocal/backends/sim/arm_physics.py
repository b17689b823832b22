"""Physics for a simulated LeRobot arm: one joint plant per servo, the firmware's control law, a simulated clock.

:func:`attach_physics` turns a :class:`~robocal.backends.sim.lerobot_arms.SimArm` whose shafts are placed by hand
into one whose servos move under their firmware (:class:`~.servo_firmware.ServoFirmware`): each joint's plant has
its hard stops where the arm's truth has them (actual ticks → radians around the mid pose), the nominal physics
of :data:`ARM_NOMINAL` and the joint's :class:`~.scenarios.Scenario`. The arm's bus then advances the clock by
its latency per packet; the host sleeps on the same clock.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import replace
from typing import TYPE_CHECKING

from ...errors import UsageError
from .physics import JointPlant, PlantParams, SimClock
from .scenarios import Scenario, make_plant
from .servo_firmware import RATINGS

if TYPE_CHECKING:
    from .lerobot_arms import SimArm

__all__ = ["ARM_NOMINAL", "attach_physics"]

ARM_NOMINAL = PlantParams(
    inertia_kgm2=0.004,
    coulomb_nm=0.04,
    stiction_nm=0.06,
    viscous_nms_rad=0.02,
    stiffness_lower=300.0,
    stiffness_upper=300.0,
    counts_per_rev=4096,
    encoder_on_link=True,
)
"""Nominal physics of one small-arm joint (printed links, 300 N·m/rad stops); stops come from the truth."""


def attach_physics(
    arm: SimArm,
    clock: SimClock,
    *,
    scenarios: Mapping[str, Scenario] | None = None,
    search_torque_nm: Mapping[str, float] | float | None = None,
    nominal: PlantParams = ARM_NOMINAL,
    seed: int = 0,
    gravity: Mapping[str, tuple[float, float]] | None = None,
) -> dict[str, JointPlant]:
    """Give every servo of ``arm`` a plant and its firmware, on ``clock`` (before or after :meth:`SimArm.start`).

    Args:
        arm: The simulated arm (its truth gives the stops; the joints start where the servos are).
        clock: Simulated time, shared with the host.
        scenarios: Joint → scenario (default: a clean joint).
        search_torque_nm: The torque a stop search pushes with, per joint or for all (scales the scenario's
            stiction, snag and faults); default 25 % of the servo's stall torque.
        nominal: Physics without the stops (their angles come from the truth).
        seed: Seed of the scenario draws and the encoder noise (offset per motor id).
        gravity: Joint → ``(amplitude N·m, hanging angle rad)``: the joint's gravity torque
            ``τ_g = −amplitude·sin(q − hanging)`` with ``q`` measured from the middle of its stops (e.g. a URDF's
            :class:`~robocal.core.gravity.JointGravity` in the robot profile's search pose); default none.

    Returns:
        Joint name → plant (its ``q_rad`` is 0 at the truth's mid pose).

    Raises:
        UsageError: A scenario names a joint the arm does not have.
    """
    unknown = sorted(set(scenarios or {}) - set(arm.truth))
    if unknown:
        raise UsageError(f"no joint(s) {', '.join(unknown)} on the simulated {arm.spec.name}")
    plants: dict[str, JointPlant] = {}
    with arm.bus.lock:
        for m in arm.spec.motors:
            servo = arm.servo(m.name)
            t = arm.truth[m.name]
            per_rad = servo.resolution / (2 * math.pi)
            params = replace(
                nominal,
                stop_lower_rad=(t.stop_low_ticks - t.mid_ticks) / per_rad,
                stop_upper_rad=(t.stop_high_ticks - t.mid_ticks) / per_rad,
                counts_per_rev=servo.resolution,
            )
            if isinstance(search_torque_nm, Mapping):
                torque = search_torque_nm.get(m.name)
            else:
                torque = search_torque_nm
            if torque is None:
                torque = 0.25 * RATINGS[servo.model].stall_torque_nm
            if gravity is not None and m.name in gravity:
                amplitude, hanging = gravity[m.name]
                middle = 0.5 * (t.stop_low_ticks + t.stop_high_ticks - 2 * t.mid_ticks) / per_rad
                params = replace(params, gravity_nm=amplitude, gravity_zero_rad=middle + hanging)
            scenario = (scenarios or {}).get(m.name, Scenario())
            q0 = (servo.actual_ticks - t.mid_ticks) / per_rad
            plant = make_plant(
                scenario, params, search_torque_nm=torque, seed=seed * 1000 + m.motor_id, q0_rad=q0
            )
            servo.firmware = servo.kind.firmware(servo, plant, clock, zero_ticks=t.mid_ticks)
            # the firmware's stops are the plant's; the hand's clamp must not cut a scenario's missing stop
            servo.stop_low_ticks, servo.stop_high_ticks = -1e9, 1e9
            plants[m.name] = plant
        arm.bus.use_clock(clock)
    return plants
