"""Automatic hard-stop calibration: drive each joint into its stops, safely, and compute the zeros.

The search itself is :class:`robocal.core.stop_search.StopSearch` (pure, backend-neutral); this module runs it on
:class:`JointDriver` objects — a Robstride motor over python-can (:class:`~robocal.backends.robstride.joint_driver.RobstrideJointDriver`), a Feetech or
Dynamixel servo (:mod:`robocal.backends.servo_joint_driver`) — in the order and with the torque, speed and poses of a
robot profile's ``auto_calibration`` section (:class:`robocal.core.profile_auto.AutoSection`).

Safety (docs/auto_calibration.md): every search has travel and time bounds; any exception (Ctrl-C included)
makes every driver go limp at once (:func:`limp_all`) before it propagates; nothing is written here (the callers
write files only once every joint passed, or with ``partial``).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field

from ...core.gravity import GravityModel, JointGravity, joint_gravity
from ...core.profile_auto import NOT_SEARCHED, AutoJoint, AutoSection
from ...core.stop_zero import JointStops
from ...errors import DeviceError, DeviceGoneError, UsageError
from .group import run_lockstep
from .joint import TRANSIT_FACTOR, calibrate_joint, calibrate_joint_steps, drive, move_to
from .model import *  # noqa: F403  (robocal.workflows.autocal keeps the public names of autocal_types)
from .model import (
    AutoCalAbortedError,
    AutoCalResult,
    AutoView,
    Clock,
    JointDriver,
    JointOutcome,
    limp_all,
    limp_on_error,
)
from .model import __all__ as _types_all

__all__ = [
    "AutoCalRequest",
    "calibrate_joint",
    "joint_gravity_for",
    "run_autocal",
    "select_joints",
]
__all__ += _types_all


# ------------------------------------------------------------------------------------------------ a robot
def select_joints(
    section: AutoSection, joints: Sequence[str] | None, *, movable_only: bool = False
) -> tuple[AutoJoint, ...]:
    """The profile's joints in search order, restricted to ``joints`` (``--joints``) when given.

    Args:
        section: The profile's auto-calibration section.
        joints: The joints asked for (None: every joint of the section).
        movable_only: Refuse a named joint the profile gives no hard stop (``stops: none``): a user who names
            it asks for something that cannot be done (the CLI's ``--joints``).

    Raises:
        UsageError: ``joints`` is empty, names a joint the profile's auto_calibration section lacks, or (with
            ``movable_only``) a joint without stops.
    """
    if joints is None:
        return section.joints
    if not joints:
        raise UsageError("--joints: give at least one joint name")
    unknown = [n for n in joints if section.joint(n) is None]
    if unknown:
        raise UsageError(
            f"--joints: no auto-calibration entry for {', '.join(unknown)}; joints: {', '.join(section.joint_names)}"
        )
    wanted = set(joints)
    chosen = tuple(j for j in section.joints if j.name in wanted)
    stopless = [j for j in chosen if not j.searched]
    if movable_only and stopless:
        why = "; ".join(f"{j.name}: {j.reason or 'no hard stop in the profile'}" for j in stopless)
        raise UsageError(
            f"--joints: {', '.join(j.name for j in stopless)} cannot be auto-calibrated, the profile gives "
            f"{'it' if len(stopless) == 1 else 'them'} no hard stop ({why})"
        )
    return chosen


@dataclass
class _Run:
    offsets: dict[str, float] = field(default_factory=dict)


@dataclass(frozen=True, eq=False)
class AutoCalRequest:
    """Which joints of a profile's auto-calibration section :func:`run_autocal` searches, and how.

    Attributes:
        section: The profile's auto-calibration section.
        limits: Joint → URDF (lower, upper) limits (rad), the default expected stop angles.
        joints: Subset to calibrate (``--joints``), in the profile's order (None: every joint).
        max_lag_rad: Per joint or for all: the most the position target may lead the joint (the drive's
            ``cap/kp``).
        gravity: Joint → gravity torque model ``τ_g(s)`` in the driver's frame, for the correction.
        gravity_model: The URDF's gravity model (:func:`robocal.formats.urdf_gravity.gravity_model_from_urdf`):
            each joint's stops are corrected with its gravity torque in the joint frame, the joints its profile
            ``pose`` names at those angles and every other joint at 0 (:func:`joint_gravity_for`). Joints that
            ``gravity`` covers are left to it.
        joint_gravity: Joint → gravity torque in the joint frame in its search pose, instead of ``gravity_model``
            (a simulator's truth: the simulated OpenArm's joints, whose weights are not in a URDF).
    """

    section: AutoSection
    limits: Mapping[str, tuple[float | None, float | None]] = field(default_factory=dict)
    joints: Sequence[str] | None = None
    max_lag_rad: Mapping[str, float] | float = math.radians(3.0)
    gravity: Mapping[str, Callable[[float], float]] | None = None
    gravity_model: GravityModel | None = None
    joint_gravity: Mapping[str, JointGravity] | None = None


def run_autocal(
    drivers: Mapping[str, JointDriver],
    request: AutoCalRequest,
    *,
    view: AutoView | None = None,
    clock: Clock | None = None,
) -> AutoCalResult:
    """Auto-calibrate the joints of ``request.section`` (or its ``joints`` subset) in order.

    Before each joint, the joints already calibrated that its ``pose`` names move to those angles (their zero
    is known by then). Joints the profile puts ``alongside`` an earlier one are searched at the same time as it
    (:func:`robocal.workflows.autocal.group.run_lockstep`), their poses taken first; the outcomes stay in the
    profile's order. A joint without stops (``stops: none``, a full-turn joint) never moves and needs no
    driver: its outcome is ``not_searched`` with the profile's reason (not a failure). A joint that fails is left limp and the run goes on with the next one. Any exception —
    Ctrl-C, a lost bus — makes every driver limp before it propagates (as :class:`AutoCalAbortedError` for a
    device error, unchanged for ``KeyboardInterrupt``).

    Args:
        drivers: Joint name → driver (every selected joint needs one).
        request: The section, the joints, the lag and the gravity models.
        view: Live view.
        clock: Clock for the total time (default: the first driver's readings).

    Raises:
        UsageError: ``joints`` names a joint the section lacks, or a selected joint has no driver.
        AutoCalAbortedError: A device fault (every motor is limp).
    """
    section, limits, max_lag_rad, gravity = request.section, request.limits, request.max_lag_rad, request.gravity
    gravity_model, joint_gravity = request.gravity_model, request.joint_gravity
    order = select_joints(section, request.joints)
    lacking = [j.name for j in order if j.searched and j.name not in drivers]
    if lacking:
        raise UsageError(f"no motor for joint(s) {', '.join(lacking)}")
    run = _Run()
    outcomes: list[JointOutcome] = []
    moving = [j for j in order if j.searched]
    if not moving:
        return AutoCalResult(tuple(_not_searched(j) for j in order), 0.0)
    t_start = clock.now() if clock is not None else drivers[moving[0].name].read().t_s
    with limp_on_error(drivers):
        try:
            for group in _groups(section, order):
                searched = [j for j in group if j.searched]
                for joint in searched:
                    for other, angle_deg in joint.pose:
                        if other in run.offsets and other in drivers:
                            move_to(
                                drivers[other],
                                math.radians(angle_deg) + run.offsets[other],
                                section.joint(other).speed_rad_s * TRANSIT_FACTOR,  # type: ignore[union-attr]
                                section.joint(other).torque_cap_nm,  # type: ignore[union-attr]
                                _lag(max_lag_rad, other),
                            )
                steps = {}
                for joint in searched:
                    steps[joint.name] = calibrate_joint_steps(
                        drivers[joint.name],
                        joint,
                        section,
                        joint.expected_rad(*limits.get(joint.name, (None, None))),
                        max_lag_rad=_lag(max_lag_rad, joint.name),
                        gravity=None if gravity is None else gravity.get(joint.name),
                        gravity_joint=None
                        if gravity is not None and joint.name in gravity
                        else (joint_gravity or {}).get(joint.name) or joint_gravity_for(gravity_model, joint),
                        view=view,
                    )
                if len(steps) == 1:
                    (name, st), = steps.items()
                    done = {name: drive(drivers[name], st)}
                else:
                    done = run_lockstep(drivers, steps, clock)
                for joint in group:
                    outcome = done[joint.name] if joint.searched else _not_searched(joint)
                    outcomes.append(outcome)
                    if outcome.ok:
                        run.offsets[joint.name] = outcome.stops.offset_rad
        except (DeviceError, AutoCalAbortedError) as exc:
            unsure = limp_all(drivers)
            limp = "every motor limp" if not unsure else f"{', '.join(unsure)} did not answer the torque-off"
            if isinstance(exc, DeviceGoneError):  # nothing reached the motors: the guard's clause says what now
                limp = "the device is gone"
            raise AutoCalAbortedError(f"auto-calibration aborted, {limp}: {exc}") from None
    t_end = clock.now() if clock is not None else drivers[moving[-1].name].read().t_s
    rank = {j.name: i for i, j in enumerate(order)}
    outcomes.sort(key=lambda o: rank[o.name])
    return AutoCalResult(tuple(outcomes), t_end - t_start)


def _groups(section: AutoSection, order: Sequence[AutoJoint]) -> list[list[AutoJoint]]:
    """``order`` (the selected joints) in run order, each joint with the selected ones alongside it."""
    wanted = {j.name for j in order}
    out = [[j for j in g if j.name in wanted] for g in section.groups()]
    return [g for g in out if g]


def _not_searched(joint: AutoJoint) -> JointOutcome:
    """The outcome of a joint without stops: nothing moved, the profile's reason."""
    reason = joint.reason or "the profile gives it no hard stop"
    stops = JointStops(joint.name, NOT_SEARCHED, reason, None, None, math.nan)
    return JointOutcome(stops, 0.0, joint.speed_rad_s, 0.0)


def joint_gravity_for(model: GravityModel | None, joint: AutoJoint) -> JointGravity | None:
    """The gravity torque of ``joint`` from ``model`` in its search pose (None: no model, or not a revolute joint of it).

    The joints the profile's ``pose`` names hold those angles; every other joint is taken at 0 (the URDF's zero
    pose), so the correction is exact for a profile that names the pose of every joint that carries weight.
    """
    if model is None or joint.name not in model.joint_names or model.joint(joint.name).type != "revolute":
        return None
    pose = {name: math.radians(deg) for name, deg in joint.pose if name in model.joint_names}
    return joint_gravity(model, joint.name, pose)


def _lag(value: Mapping[str, float] | float, name: str) -> float:
    return float(value[name]) if isinstance(value, Mapping) else float(value)
