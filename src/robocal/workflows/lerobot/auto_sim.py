"""The arm ``lerobot calibrate --auto`` drives: a real port, or a simulated SO-101 / Koch with physics (``sim``).

``--port sim`` (or ``sim?seed=3&missing=wrist_flex&...``) starts a :class:`~robocal.backends.sim.lerobot_arms.SimArm`
on a pseudo-terminal whose servos move under their simulated firmware (:func:`~robocal.backends.sim.arm_physics.
attach_physics`) on a simulated clock; robocal talks to it through the vendor SDK like to a real arm. Options:
``seed`` (the arm's truth varies per seed, :func:`~robocal.backends.sim.lerobot_arms.seeded_truth`) and, as
comma-separated joint names, ``missing`` (no upper stop), ``obstacle``, ``snag``, ``soft``, ``overload``,
``silent``, ``stiction`` (the scenarios of ``sim:lite``, docs/auto_calibration.md).
"""

from __future__ import annotations

import contextlib
from collections.abc import Iterator, Mapping
from dataclasses import dataclass
from typing import Any

from ...backends.servo_bus import ServoBus
from ...backends.servo_ratings import RATINGS
from ...core.lerobot import RobotSpec
from ...core.profile_auto import AutoSection
from ...errors import UsageError
from ..autocal import Clock, MonotonicClock
from ..autocal_sim import SIM_FAULTS, fault_scenario
from .arms import open_bus

__all__ = ["AutoArm", "open_auto_arm", "parse_sim_port"]


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
        UsageError: Malformed options, an unknown option or joint name.
    """
    if port != "sim" and not port.startswith("sim?"):
        return None
    from ...backends.sources.spec import parse_sim_options

    opts = parse_sim_options(port, port.partition("?")[2], ("seed", *SIM_FAULTS), joined=SIM_FAULTS)
    for key in SIM_FAULTS:
        bad = sorted({n for n in opts.get(key, "").split(",") if n} - set(spec.motor_names))
        if bad:
            raise UsageError(f"--port {port!r}: {key}: no joint(s) {', '.join(bad)} on a {spec.name}")
    return opts


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
    faults = {k: {n for n in opts.get(k, "").split(",") if n} for k in SIM_FAULTS}
    scenarios = {m.name: fault_scenario(m.name, faults) for m in spec.motors}
    push: dict[str, float] = {}
    for m in spec.motors:
        joint = section.joint(m.name)
        fraction = joint.torque_fraction if joint is not None and joint.searched else 0.25
        push[m.name] = fraction * RATINGS[m.model].stall_torque_nm
    clock = SimClock()
    with SimArm(spec, truth=truth if truth is not None else seeded_truth(spec.name, seed)) as arm:
        plants = attach_physics(arm, clock, scenarios=scenarios, search_torque_nm=push, seed=seed or 0)
        bus = open_bus(spec, arm.port)
        try:
            yield AutoArm(bus, clock, arm, plants)
        finally:
            bus.close()
