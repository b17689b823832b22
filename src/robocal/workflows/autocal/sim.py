"""Simulated robots for the automatic hard-stop calibration: physics behind the real wire protocols.

:func:`open_sim_lite` builds the 14 Lite arm joints as simulated Robstride motors (``robocal.backends.sim``)
whose MIT commands move a :class:`~robocal.backends.sim.physics.JointPlant` each, on one simulated clock, on two
python-can ``virtual`` channels; the drivers are the same :class:`~robocal.backends.robstride.joint_driver.RobstrideJointDriver`
that drives real motors through :class:`~robocal.backends.robstride.RobstrideBus`. Used by
``robocal sweep --auto --source sim:lite?...``, ``robocal demo --auto`` and the tests.

Source options (``sim:lite?seed=3&missing=left_wrist_roll&snag=right_elbow_pitch&soft=...``): ``seed``; joints
with a ``missing`` upper stop, a mid-travel ``obstacle``, a cable ``snag``, ``soft`` 15 N·m/rad stops, an
``overload`` latch or a motor ``silent`` at the stop (comma-separated joint names).
"""

from __future__ import annotations

from collections.abc import Callable, Collection, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from ...core.profile import RobotProfile
from ...errors import UsageError
from .model import JointDriver, joint_driver_class

if TYPE_CHECKING:
    from ...backends.sim.physics import Scenario

__all__ = [
    "SIM_FAULTS",
    "SimAutoLite",
    "fault_scenario",
    "open_sim_lite",
    "sim_opener",
    "write_sim_lite_urdf",
]

SIM_FAULTS = ("missing", "obstacle", "snag", "soft", "overload", "silent", "stiction")
"""Per-joint scenario options of ``sim:lite`` for ``--auto``."""


def fault_scenario(joint: str, faults: Mapping[str, Collection[str]]) -> Scenario:
    """The simulated joint's :class:`~robocal.backends.sim.scenarios.Scenario` from the per-fault joint lists.

    Args:
        joint: The joint's name.
        faults: For each of :data:`SIM_FAULTS`, the joints that have that fault.
    """
    from ...backends.sim.physics import Scenario

    return Scenario(
        soft_stop=joint in faults["soft"],
        missing_stop="upper" if joint in faults["missing"] else "none",
        obstacle=joint in faults["obstacle"],
        cable_snag=joint in faults["snag"],
        overload_latch=joint in faults["overload"],
        silent_at_stop=joint in faults["silent"],
        stiction_ratio=0.8 if joint in faults["stiction"] else 0.0,
    )


@dataclass
class SimAutoLite:
    """The simulated Lite of an auto run (after :func:`open_sim_lite`).

    Attributes:
        drivers: Joint → driver (over the wire).
        clock: The simulated clock.
        motors: Joint → simulated motor (its ``true_homing_offset_rad`` is the truth).
        buses: The simulated buses and the robocal buses (closed by :meth:`close`).
    """

    drivers: dict[str, JointDriver]
    clock: Any
    motors: dict[str, Any]
    buses: list[Any]

    def true_offsets(self) -> dict[str, float]:
        """Joint → true homing offset (motor frame, rad)."""
        return {n: float(m.true_homing_offset_rad) for n, m in self.motors.items()}

    def close(self) -> None:
        """Close every bus."""
        for b in self.buses:
            try:
                b.close()
            except AttributeError:
                b.stop()
        self.buses = []


def _names(options: Mapping[str, str], key: str, known: set[str]) -> set[str]:
    items = {x for x in options.get(key, "").split(",") if x}
    bad = sorted(items - known)
    if bad:
        raise UsageError(f"sim:lite {key}: unknown joint(s) {', '.join(bad)}")
    return items


def open_sim_lite(
    options: Mapping[str, str],
    joints: Sequence[Any],
    profile: RobotProfile,
    *,
    timeout_s: float = 1.0,
) -> SimAutoLite:
    """Build the simulated Lite for ``joints`` (URDF specs) with the profile's caps.

    Raises:
        UsageError: A joint the simulated Lite does not have, or a bad option.
    """
    from ...backends import load_backend
    from ...backends.robstride import MotorSpec
    from ...backends.robstride.bus import DEFAULT_TIMEOUT_S as HARDWARE_TIMEOUT_S
    from ...backends.robstride.sim import SimMotor, SimMotorBus
    from ...backends.sim.lite import LITE_JOINTS
    from ...backends.sim.lite_physics import lite_plant_params
    from ...backends.sim.physics import SimClock, make_plant

    table = {j.name: j for j in LITE_JOINTS}
    names = {j.name for j in joints}
    unknown = sorted(names - set(table))
    if unknown:
        raise UsageError(f"sim:lite has no joint(s) {', '.join(unknown)}")
    unknown_opts = sorted(set(options) - {"seed", *SIM_FAULTS})
    if unknown_opts:
        raise UsageError(
            f"sim:lite: unknown option(s) {', '.join(unknown_opts)}; expected seed, {', '.join(SIM_FAULTS)}"
        )
    try:
        seed = int(options.get("seed", "0"))
    except ValueError:
        raise UsageError(f"sim:lite seed {options.get('seed')!r}: expected an integer") from None
    faults = {k: _names(options, k, names) for k in SIM_FAULTS}
    auto = profile.auto
    assert auto is not None
    rng = np.random.default_rng(seed)
    clock = SimClock()
    motors: dict[str, Any] = {}
    for j in LITE_JOINTS:
        if j.name not in names:
            continue
        aj = auto.joint(j.name)
        cap = aj.torque_cap_nm if aj is not None else 1.0
        fz = float(rng.uniform(-1.0, 1.0))
        margin = min(0.6, 0.25 * (j.upper - j.lower))
        q0 = float(rng.uniform(j.lower + margin, j.upper - margin))
        nominal = lite_plant_params(j.model, j.lower, j.upper, cap)  # as the standalone Lite's
        scen = fault_scenario(j.name, faults)
        plant = make_plant(scen, nominal, search_torque_nm=cap, seed=seed * 1000 + j.can_id, q0_rad=q0)
        motors[j.name] = SimMotor(
            can_id=j.can_id,
            model=j.model,
            direction=j.direction,
            factory_zero_rad=fz,
            stop_lower_rad=j.lower - 1.0,
            stop_upper_rad=j.upper + 1.0,
            noise_rad=0.0,
            zero_sta=1,
            q_rad=q0,
            seed=seed * 1000 + j.can_id,
            plant=plant,
            clock=clock,
        )
    prefix = f"robocal-autocal-lite-{id(clock)}"
    buses: list[Any] = []
    drivers: dict[str, JointDriver] = {}
    by_spec = {j.name: j for j in joints}
    try:
        for bus_name in ("can0", "can1"):
            on_bus = [table[n] for n in motors if table[n].bus == bus_name]
            if not on_bus:
                continue
            channel = f"{prefix}-{bus_name}"
            sim_bus = SimMotorBus(channel, [motors[j.name] for j in on_bus], interface="virtual")
            sim_bus.start()
            buses.append(sim_bus)
            bus = load_backend("robstride")(
                channel,
                [MotorSpec(j.name, j.can_id, j.model) for j in on_bus],
                interface="virtual",
                timeout_s=timeout_s,
            )
            buses.insert(0, bus)
            for j in on_bus:
                aj = auto.joint(j.name)
                cap = aj.torque_cap_nm if aj is not None else 1.0
                driver_cls = joint_driver_class("robstride")
                drivers[j.name] = driver_cls(
                    bus,
                    j.name,
                    by_spec[j.name].direction,
                    cap,
                    driver_cls.MAX_LAG_RAD,
                    clock,
                    lost_reply_s=HARDWARE_TIMEOUT_S,
                )
    except BaseException:
        SimAutoLite(drivers, clock, motors, buses).close()
        raise
    return SimAutoLite(drivers, clock, motors, buses)


def sim_opener(holder: list[SimAutoLite] | None = None) -> Callable[..., Any]:
    """An ``open_drivers_fn`` for ``run_sweep_auto`` with ``sim:lite``; the robot is appended to ``holder``."""

    def open_(
        spec: Any, joints: Sequence[Any], profile: RobotProfile
    ) -> tuple[dict[str, JointDriver], Any, Any]:
        sim = open_sim_lite(spec.options, joints, profile)
        if holder is not None:
            holder.append(sim)
        return sim.drivers, sim.clock, sim.close

    return open_


def write_sim_lite_urdf(path: Path) -> Path:
    """Write the simulated Lite's URDF (14 arm joints) to ``path`` atomically; return ``path``."""
    from ...backends.sim.lite import lite_urdf_text
    from ...fileio import atomic_write_text

    atomic_write_text(path, lite_urdf_text(), backup=False)
    return path
