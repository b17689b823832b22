"""The arm ``lerobot calibrate --auto`` drives: a real port, or a simulated SO-101 / Koch with physics (``sim``).

``--port sim`` (or ``sim?seed=3&missing=wrist_flex&...``) starts a :class:`~robocal.backends.sim.lerobot_arms.SimArm`
on a pseudo-terminal whose servos move under their simulated firmware (:func:`~robocal.backends.sim.arm_physics.
attach_physics`) on a simulated clock; robocal talks to it through the vendor SDK like to a real arm. Options:
``seed`` (the arm's truth varies per seed, :func:`~robocal.backends.sim.lerobot_arms.seeded_truth`: the searched
joints' stops drawn around the profile's expected angles, each within ``span_tolerance_deg``/2 − 0.5° of it, so a
seeded arm is one the profile accepts unless a scenario says otherwise) and, as
comma-separated joint names, ``missing`` (no upper stop), ``obstacle``, ``snag``, ``soft``, ``overload``,
``silent``, ``stiction`` (the scenarios of ``sim:lite``, docs/auto_calibration.md) and ``gravity`` (those joints
carry the shipped URDF's weight in their profile search pose; without it the simulated joints are weightless), and
``transport`` (``pty``, the default: a pseudo-terminal as a real arm has; ``inproc``: the same packets through an
in-process port, the SDK's bytes handed straight to the simulator, several times faster in wall time). The
simulated STS3215 is the follower's 7.4 V servo (1.91 N·m), the rating its profile uses.
"""

from __future__ import annotations

import contextlib
import math
import os
from collections.abc import Iterator, Mapping
from dataclasses import dataclass
from typing import Any

from ...backends.servo_bus import ServoBus
from ...backends.servo_ratings import RATINGS
from ...core.gravity import GravityModel
from ...core.lerobot import RobotSpec
from ...core.profile_auto import AutoSection
from ...errors import UsageError
from ..autocal.job import joint_gravity_for
from ..autocal.model import Clock, MonotonicClock
from ..autocal.sim import SIM_FAULTS, fault_scenario
from .arms import check_simulated, open_bus, open_sim_bus

ARM_OPTIONS = (*SIM_FAULTS, "gravity")
"""Per-joint options of a simulated LeRobot arm: the scenarios of ``sim:lite`` and ``gravity`` (the joint carries
its shipped URDF's weight in its profile search pose)."""

SIM_TRANSPORTS = ("pty", "inproc")
"""Values of the ``transport`` option of a simulated arm's port."""

__all__ = [
    "ARM_OPTIONS",
    "SIM_TRANSPORTS",
    "SPREAD_MARGIN_DEG",
    "AutoArm",
    "auto_gravity_model",
    "open_auto_arm",
    "parse_sim_port",
    "sim_gravity_model",
]

SPREAD_MARGIN_DEG = 0.5
"""A seeded simulated arm's stops lie within half the profile's ``span_tolerance_deg`` less this of the profile's
stop angles (each side), so its span is always inside the tolerance with room for the measurement."""


@dataclass
class AutoArm:
    """The arm of an auto run.

    Attributes:
        bus: Its bus.
        clock: The control loop's clock (the wall clock on a real port).
        sim: The simulated arm (None on a real port); ``plants`` its joints' physics.
        plants: Joint → :class:`~robocal.backends.sim.physics.JointPlant` (simulated arm only).
    """

    bus: ServoBus
    clock: Clock
    sim: Any = None
    plants: Mapping[str, Any] | None = None


def parse_sim_port(port: str, spec: RobotSpec) -> dict[str, str] | None:
    """The options of a ``sim`` / ``sim?...`` port (None for a real port).

    Raises:
        UsageError: Malformed options, an unknown option or joint name, or an arm the simulator does not have (a
            profile file).
    """
    if port != "sim" and not port.startswith("sim?"):
        return None
    from ...backends.sources.spec import parse_sim_options

    check_simulated(spec, port)

    opts = parse_sim_options(
        port, port.partition("?")[2], ("seed", "transport", *ARM_OPTIONS), joined=ARM_OPTIONS
    )
    transport = opts.get("transport", "pty")
    if transport not in SIM_TRANSPORTS:
        raise UsageError(f"--port {port!r}: transport {transport!r}: expected one of {', '.join(SIM_TRANSPORTS)}")
    for key in ARM_OPTIONS:
        bad = sorted({n for n in opts.get(key, "").split(",") if n} - set(spec.motor_names))
        if bad:
            raise UsageError(f"--port {port!r}: {key}: no joint(s) {', '.join(bad)} on a {spec.name}")
    return opts


def sim_gravity_model(spec: RobotSpec) -> GravityModel | None:
    """The gravity model of the simulated arm's shipped URDF (SO-101: ``so101_new_calib.urdf``'s masses).

    None for an arm whose shipped URDF has no masses (the Koch's ``koch.urdf``) or that has none shipped.
    """
    from ...backends.sim.kinematic_arm import SIM_ROBOTS, shipped_urdf
    from ...formats.urdf_gravity import gravity_model_if_any

    robot = spec.name.split("_")[0]
    if robot not in SIM_ROBOTS:
        return None
    return gravity_model_if_any(shipped_urdf(robot))


def auto_gravity_model(
    spec: RobotSpec, port: str, section: AutoSection, urdf: str | os.PathLike[str] | None
) -> GravityModel | None:
    """The gravity model the stop-zero correction of ``lerobot calibrate --auto`` uses.

    ``urdf`` (``--urdf``) when given: its ``<inertial>`` masses; else, on a simulated arm, its shipped URDF's
    (:func:`sim_gravity_model`); else none (a real arm without ``--urdf``: no correction).

    Raises:
        UsageError: ``urdf`` has no masses, or none of the searched joints.
        FileFormatError: A malformed URDF.
    """
    if urdf is None:
        return sim_gravity_model(spec) if parse_sim_port(port, spec) is not None else None
    from ...formats.urdf_gravity import gravity_model_if_any

    model = gravity_model_if_any(urdf)
    if model is None:
        raise UsageError(
            f"--urdf {os.fspath(urdf)}: no link has an <inertial> mass: no gravity model to correct with"
        )
    searched = [j.name for j in section.searched_joints]
    if not any(n in model.joint_names for n in searched):
        raise UsageError(
            f"--urdf {os.fspath(urdf)}: none of the searched joints ({', '.join(searched)}) is a joint of it"
        )
    return model


@contextlib.contextmanager
def open_auto_arm(
    spec: RobotSpec, port: str, section: AutoSection, *, truth: Mapping[str, Any] | None = None
) -> Iterator[AutoArm]:
    """Open the arm on ``port``; ``sim``/``sim?...`` starts a simulated arm with physics first.

    ``truth`` (simulated arm only): joint → :class:`~robocal.backends.sim.lerobot_arms.JointTruth` instead of
    the seed's.

    The simulated scenarios scale with the torque the search pushes with: each joint's profile fraction of the
    model's stall torque (what ``Torque_Limit`` / ``Goal_Current`` give on the simulated firmware).
    """
    opts = parse_sim_port(port, spec)
    if opts is None:
        bus = open_bus(spec, port)
        try:
            yield AutoArm(bus, MonotonicClock())
        finally:
            bus.close()
        return
    from ...backends.sim.arm_physics import attach_physics
    from ...backends.sim.lerobot_arms import SimArm, seeded_truth
    from ...backends.sim.physics import SimClock

    seed = int(opts["seed"]) if "seed" in opts else None
    faults = {k: {n for n in opts.get(k, "").split(",") if n} for k in ARM_OPTIONS}
    scenarios = {m.name: fault_scenario(m.name, faults) for m in spec.motors}
    push: dict[str, float] = {}
    for m in spec.motors:
        joint = section.joint(m.name)
        fraction = joint.torque_fraction if joint is not None and joint.searched else 0.25
        push[m.name] = fraction * RATINGS[m.model].stall_torque_nm
    clock = SimClock()
    if truth is None:
        expected = {
            j.name: (j.lower_deg, j.upper_deg)
            for j in section.searched_joints
            if j.lower_deg is not None and j.upper_deg is not None
        }
        spread = max(0.0, 0.5 * section.span_tolerance_deg - SPREAD_MARGIN_DEG)
        truth = seeded_truth(spec.name, seed, expected_deg=expected, stop_spread_deg=spread)
    gravity: dict[str, tuple[float, float]] = {}
    model = sim_gravity_model(spec)
    for j in section.searched_joints:  # the arm's own weight on the joints asked, in each one's search pose
        jg = joint_gravity_for(model, j) if j.name in faults["gravity"] else None
        if jg is not None and j.lower_deg is not None and j.upper_deg is not None:
            middle = math.radians(0.5 * (j.lower_deg + j.upper_deg))
            gravity[j.name] = (jg.amplitude_nm, jg.hanging_rad - middle)
    with SimArm(spec, truth=truth, transport=opts.get("transport", "pty")) as arm:
        plants = attach_physics(
            arm, clock, scenarios=scenarios, search_torque_nm=push, seed=seed or 0, gravity=gravity
        )
        bus = open_sim_bus(spec, arm, port)
        try:
            yield AutoArm(bus, clock, arm, plants)
        finally:
            bus.close()
