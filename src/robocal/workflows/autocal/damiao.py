"""``sweep --auto`` on Damiao motors: the live buses (``can:``) and the simulated OpenArm (``sim:openarm``).

Each profile bus is one :class:`~robocal.backends.damiao.bus.DamiaoBus` opened with ``allow_motion=True`` (the
guarded path: :func:`robocal.workflows.autocal.sweep.run_sweep_auto` enters the motion guard before the first
frame that moves), its motors named by the profile's URDF joint names with their ``id`` (ESC_ID) and ``reply_id``
(MST_ID); each joint is a :class:`~robocal.backends.damiao.joint_driver.DamiaoJointDriver`.

``sim:openarm?seed=N&missing=...&snag=...`` builds :class:`~robocal.backends.damiao.openarm.SimOpenArm` (the side
from the profile) with the scenario options of ``sim:lite`` (joint names as the URDF names them), on python-can's
``virtual`` interface and a simulated clock, and drives it through the same bus and drivers as a real arm.
``zeroed=1``: the motors hold the joints' zeros (as after ``--write-zero``); ``zero_drift=joint:deg,...``: those
motors' stored zeros moved since, each reading ``deg`` more than its joint (what ``--verify`` is for).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

from ...core.gravity import JointGravity
from ...core.profile import RobotProfile
from ...errors import UsageError
from .model import JointDriver
from .sim import SIM_FAULTS, fault_scenario

__all__ = ["SimAutoOpenArm", "open_damiao", "open_sim_openarm", "openarm_gravity", "openarm_side", "sim_openarm_opener"]


def openarm_side(profile: RobotProfile) -> str:
    """``right`` or ``left``: the side the profile's joint names say (``openarm_left_joint1`` → left).

    Raises:
        UsageError: The profile names no OpenArm joints.
    """
    for side in ("right", "left"):
        if all(j.name.startswith(f"openarm_{side}_") for j in profile.joints):
            return side
    raise UsageError(f"profile {profile.name}: its joints are not one OpenArm arm's (openarm_right_… / openarm_left_…)")


def _drivers(
    buses: Sequence[Any], joints: Sequence[Any], profile: RobotProfile, clock: Any, lost_reply_s: float | None
) -> dict[str, JointDriver]:
    from .model import joint_driver_class

    driver_cls = joint_driver_class("damiao")
    auto = profile.auto
    assert auto is not None
    by_name = {j.name: j for j in joints}
    drivers: dict[str, JointDriver] = {}
    for bus in buses:
        for name in bus.motors:
            aj = auto.joint(name)
            if aj is None or not aj.searched:
                continue
            drivers[name] = driver_cls(
                bus, name, by_name[name].direction, aj.torque_cap_nm, driver_cls.MAX_LAG_RAD, clock,
                lost_reply_s=lost_reply_s,
            )
    return drivers


def open_damiao(
    spec: Any, joints: Sequence[Any], profile: RobotProfile
) -> tuple[dict[str, JointDriver], Any, Callable[[], None]]:
    """The drivers of a live ``can:<interface>:<channel>[,...]`` source: the profile's buses in its order.

    The channels are taken in the order of the profile's buses (``can:socketcan:can0`` for one arm).
    """
    from ...backends import load_backend
    from ...backends.damiao.bus import motors_by_bus
    from .model import MonotonicClock

    if spec.kind != "can":
        raise UsageError(f"--auto needs a live source (can:...) or sim:openarm, not {spec.kind}")
    by_bus = motors_by_bus(profile, [j.name for j in joints])
    if len(spec.channels) != len(by_bus):
        raise UsageError(
            f"--source {spec.text!r}: profile {profile.name} has {len(by_bus)} CAN bus(es) "
            f"({', '.join(str(b) for b in by_bus)}); give one channel each"
        )
    options = {k: v for k, v in spec.options.items() if k in ("host", "port")}
    from ..motion.damiao_watchdog import note_left_zeros_on

    left = note_left_zeros_on(spec)  # before the buses open: said even when they do not
    bus_cls = load_backend("damiao")
    buses: list[Any] = []
    try:
        for channel, motors in zip(spec.channels, by_bus.values(), strict=True):
            buses.append(
                bus_cls(channel, motors, interface=spec.interface, allow_motion=True, bus_kwargs=options or None)
            )
    except BaseException:
        for b in buses:
            b.close()
        raise
    clock = MonotonicClock()

    def close() -> None:
        for b in buses:
            b.close()

    try:
        drivers = _drivers(buses, joints, profile, clock, None)
        _keep_watchdog_records(buses, drivers, spec.interface, options, left)
    except BaseException:
        close()
        raise
    return drivers, clock, close


def _keep_watchdog_records(
    buses: Sequence[Any],
    drivers: Mapping[str, Any],
    interface: str,
    options: Mapping[str, Any],
    left: Mapping[str, Any],
) -> None:
    """Per bus: put back the TIMEOUT a killed run left armed (a note), record what this run arms and stores.

    ``left``: channel → the zeros a killed run left (:func:`~..motion.damiao_watchdog.note_left_zeros`), carried on.
    """
    from ..motion.damiao_watchdog import WatchdogRecord, bus_key, restore_left_armed

    for bus in buses:
        key = bus_key(interface, bus.channel, options)
        restore_left_armed(bus, key)
        record = WatchdogRecord(key, zeros=left.get(bus.channel))
        for name in bus.motors:
            if name in drivers:
                drivers[name].on_watchdog = record.changed
                drivers[name].on_zero = record.zero


def openarm_gravity(profile: RobotProfile) -> dict[str, JointGravity]:
    """The simulated OpenArm's gravity per URDF joint, joint frame (``τ = −A·sin q``; the simulator's truth).

    On the simulated arm this stands in for the URDF masses robocal's OpenArm URDF does not have.
    """
    from ...backends.damiao.openarm import openarm_joints

    side = openarm_side(profile)
    truth = {j.name: j for j in openarm_joints(side)}  # type: ignore[arg-type]
    out: dict[str, JointGravity] = {}
    for j in profile.joints:
        t = truth.get(j.upstream_name)
        if t is not None and t.gravity_nm:
            out[j.name] = JointGravity(j.name, 0.0, -t.gravity_nm)
    return out


@dataclass
class SimAutoOpenArm:
    """The simulated OpenArm of an auto run (after :func:`open_sim_openarm`).

    Attributes:
        arm: The simulated arm (its truth: ``joint_rad``, ``zero_error_rad``, ``motors``, ``plants``).
        bus: robocal's bus to it.
        drivers: URDF joint name → driver.
        names: URDF joint name → the simulator's (LeRobot's) motor name.
    """

    arm: Any
    bus: Any
    drivers: dict[str, JointDriver]
    names: dict[str, str] = field(default_factory=dict)

    @property
    def clock(self) -> Any:
        """The simulated clock."""
        return self.arm.clock

    def close(self) -> None:
        """Close robocal's bus and stop the simulator."""
        if self.bus is not None:
            self.bus.close()
            self.bus = None
        self.arm.stop()


def open_sim_openarm(
    options: Mapping[str, str], joints: Sequence[Any], profile: RobotProfile, *, zeroed: bool = False
) -> SimAutoOpenArm:
    """Build the simulated OpenArm of the profile's side and robocal's drivers for it.

    Raises:
        UsageError: A bad option or a joint the simulated arm does not have.
    """
    from ...backends.damiao.bus import DEFAULT_TIMEOUT_S, motors_by_bus
    from ...backends.damiao.openarm import SimOpenArm
    from ...backends.sim.physics import SimClock

    side = openarm_side(profile)
    unknown = sorted(set(options) - {"seed", "zeroed", "zero_drift", *SIM_FAULTS})
    if unknown:
        raise UsageError(
            f"sim:openarm: unknown option(s) {', '.join(unknown)}; expected seed, zeroed, zero_drift, "
            f"{', '.join(SIM_FAULTS)}"
        )
    if options.get("zeroed", "0") not in ("0", "1"):
        raise UsageError(f"sim:openarm zeroed={options['zeroed']!r}: expected 0 or 1")
    zeroed = zeroed or options.get("zeroed") == "1"
    try:
        seed = int(options.get("seed", "0"))
    except ValueError:
        raise UsageError(f"sim:openarm seed {options.get('seed')!r}: expected an integer") from None
    upstream = {j.name: j.upstream_name for j in profile.joints}
    faults: dict[str, set[str]] = {}
    for key in SIM_FAULTS:
        items = {x for x in options.get(key, "").split(",") if x}
        bad = sorted(items - set(upstream))
        if bad:
            raise UsageError(f"sim:openarm {key}: unknown joint(s) {', '.join(bad)}; joints: {', '.join(upstream)}")
        faults[key] = {upstream[x] for x in items}
    auto = profile.auto
    assert auto is not None
    caps = {upstream[j.name]: j.torque_cap_nm for j in auto.searched_joints if j.name in upstream}
    scenarios = {name: fault_scenario(name, faults) for name in upstream.values()}
    drifts = _zero_drifts(options.get("zero_drift", ""), upstream)
    clock = SimClock()
    arm = SimOpenArm(
        f"robocal-autocal-openarm-{id(clock)}",
        side=side,  # type: ignore[arg-type]
        seed=seed,
        zeroed=zeroed,
        scenarios=scenarios,
        search_torque_nm=caps,
        clock=clock,
    )
    for motor, drift_rad in drifts.items():  # the stored zero moved: the motor reads drift_rad more than the joint
        m = arm.motors[motor]
        m.zero_abs_rad = (m.zero_abs_rad - drift_rad) % math.tau
        m.power_on()
    arm.start()
    sim = SimAutoOpenArm(arm, None, {}, dict(upstream))
    try:
        from ...backends import load_backend

        motors = motors_by_bus(profile, [j.name for j in joints])
        (on_bus,) = motors.values()
        sim.bus = load_backend("damiao")(arm.channel, on_bus, interface="virtual", allow_motion=True, timeout_s=1.0)
        sim.drivers = _drivers([sim.bus], joints, profile, clock, DEFAULT_TIMEOUT_S)
    except BaseException:
        sim.close()
        raise
    return sim


def _zero_drifts(text: str, upstream: Mapping[str, str]) -> dict[str, float]:
    """``zero_drift=joint:deg,...``: the simulator's motor name → how far its stored zero moved, rad."""
    out: dict[str, float] = {}
    for item in [x for x in text.split(",") if x]:
        joint, _, amount = item.partition(":")
        try:
            value = float(amount)
        except ValueError:
            value = math.nan
        if joint not in upstream or not math.isfinite(value):
            raise UsageError(f"sim:openarm zero_drift: expected joint:degrees with a joint of the profile, got {item!r}")
        out[upstream[joint]] = math.radians(value)
    return out


def sim_openarm_opener(holder: list[SimAutoOpenArm] | None = None) -> Callable[..., Any]:
    """An ``open_drivers_fn`` for ``run_sweep_auto`` with ``sim:openarm``; the arm is appended to ``holder``."""

    def open_(spec: Any, joints: Sequence[Any], profile: RobotProfile) -> tuple[dict[str, JointDriver], Any, Any]:
        sim = open_sim_openarm(spec.options, joints, profile)
        if holder is not None:
            holder.append(sim)
        return sim.drivers, sim.clock, sim.close

    return open_
