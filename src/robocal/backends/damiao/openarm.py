"""The simulated OpenArm v10: eight Damiao motors per arm behind joint plants, on one CAN channel.

:data:`OPENARM_V10` is the arm's physical truth in one place (joint frame, rad; the right arm): ids and models
(OA, LR ``config_openarm_follower.py``, OAC's zero-position script), the stops at the URDF limits (OAD
``config/arm/v10/joint_limits.yaml``; the left arm's J1 and J2 mirrored, :func:`openarm_joints`), and the
physics: **assumed** masses as gravity amplitudes, inertias, friction, backlash and stop stiffness (metal stops
on J1-J4, printed ones on J5-J7 and the gripper). No source gives the masses or the stop materials; the numbers
are plausible for a ~5 kg arm and are stated as assumptions in docs/damiao.md.

Each joint's motor is mounted at a hidden angle (:attr:`SimDamiaoMotor.mount_rad`) and leaves the factory with
an arbitrary zero in flash, both drawn from the seed; ``zeroed=True`` instead stores the zero a perfect
calibration would (the motor reads the joint angle). The joint angle of the truth is what LeRobot's
``OpenArmFollower`` should report after a correct calibration (degrees of it).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, replace
from typing import Literal

import numpy as np

from ...core.lifecycle import StartsOnEnter
from ...errors import UsageError
from ..sim.pacer import RealtimePacer
from ..sim.physics import JointPlant, PlantParams, SimClock
from ..sim.scenarios import Scenario, make_plant
from .bus import DamiaoMotor
from .sim import MODEL_HARDWARE, SimDamiaoMotor
from .sim_bus import SimDamiaoBus
from .tables import State

__all__ = ["OPENARM_V10", "OpenArmJoint", "SimOpenArm", "openarm_joints"]

Side = Literal["right", "left"]


@dataclass(frozen=True)
class OpenArmJoint:
    """One joint of the simulated OpenArm v10 (joint frame = motor frame at a correct zero; rad, N·m, kg·m²).

    Attributes:
        name: LeRobot's motor name (``joint_1`` … ``joint_7``, ``gripper``).
        esc_id: Command id (0x01 … 0x08).
        mst_id: Reply id (0x11 … 0x18).
        model: Damiao model.
        stop_lower_rad: Lower hard stop (the URDF lower limit).
        stop_upper_rad: Upper hard stop (the URDF upper limit).
        stop_stiffness_nm_rad: Stiffness of both stops (metal ~2000, printed ~150; assumed).
        gravity_nm: Gravity torque amplitude, ``τ = −gravity_nm·sin(q)`` (0 at the hanging pose q = 0; assumed).
        inertia_kgm2: Inertia at the joint (assumed).
        coulomb_nm: Running friction (assumed; breakaway is 1.5×).
        backlash_rad: Gear play (assumed).
        rest_rad: Where the joint is at power-on (hanging arm, gripper closed).
    """

    name: str
    esc_id: int
    mst_id: int
    model: str
    stop_lower_rad: float
    stop_upper_rad: float
    stop_stiffness_nm_rad: float
    gravity_nm: float
    inertia_kgm2: float
    coulomb_nm: float
    backlash_rad: float = 0.001
    rest_rad: float = 0.0

    @property
    def peak_torque_nm(self) -> float:
        """The motor's peak torque (datasheet)."""
        return MODEL_HARDWARE[self.model].peak_torque_nm


_METAL = 2000.0
_PRINTED = 150.0
_D = math.radians

OPENARM_V10: tuple[OpenArmJoint, ...] = (
    OpenArmJoint("joint_1", 0x01, 0x11, "DM8009", _D(-80), _D(200), _METAL, 8.0, 0.30, 0.30),
    OpenArmJoint("joint_2", 0x02, 0x12, "DM8009", _D(-10), _D(190), _METAL, 8.0, 0.30, 0.30),
    OpenArmJoint("joint_3", 0x03, 0x13, "DM4340", _D(-90), _D(90), _METAL, 0.0, 0.05, 0.20),
    OpenArmJoint("joint_4", 0x04, 0x14, "DM4340", _D(0), _D(140), _METAL, 2.0, 0.04, 0.20, rest_rad=_D(2)),
    OpenArmJoint("joint_5", 0x05, 0x15, "DM4310", _D(-90), _D(90), _PRINTED, 0.0, 0.004, 0.05),
    OpenArmJoint("joint_6", 0x06, 0x16, "DM4310", _D(-45), _D(45), _PRINTED, 0.4, 0.004, 0.05),
    OpenArmJoint("joint_7", 0x07, 0x17, "DM4310", _D(-90), _D(90), _PRINTED, 0.0, 0.003, 0.05),
    OpenArmJoint(
        "gripper", 0x08, 0x18, "DM4310", _D(-60), _D(0), _PRINTED, 0.0, 0.001, 0.03, rest_rad=_D(-2)
    ),
)
"""The right arm of an OpenArm v10 (stops = OAD's v10 URDF limits; the gripper's v1 range −60°…0, closed at 0,
from OAC's zero-position script)."""


def openarm_joints(side: Side = "right") -> tuple[OpenArmJoint, ...]:
    """The joints of one arm: the left arm's J1 is −200°…80° and its J2 −190°…10° (OAD's side transforms)."""
    if side == "right":
        return OPENARM_V10
    if side != "left":
        raise UsageError(f"OpenArm side {side!r}; expected 'right' or 'left'")
    mirrored = {"joint_1", "joint_2"}
    return tuple(
        replace(j, stop_lower_rad=-j.stop_upper_rad, stop_upper_rad=-j.stop_lower_rad)
        if j.name in mirrored
        else j
        for j in OPENARM_V10
    )


def _nominal(j: OpenArmJoint) -> PlantParams:
    hw = MODEL_HARDWARE[j.model]
    return PlantParams(
        inertia_kgm2=j.inertia_kgm2,
        coulomb_nm=j.coulomb_nm,
        stiction_nm=1.5 * j.coulomb_nm,
        viscous_nms_rad=0.05 * j.coulomb_nm / 0.2,
        gravity_nm=j.gravity_nm,
        gravity_zero_rad=0.0,
        backlash_rad=j.backlash_rad,
        stop_lower_rad=j.stop_lower_rad,
        stop_upper_rad=j.stop_upper_rad,
        stiffness_lower=j.stop_stiffness_nm_rad,
        stiffness_upper=j.stop_stiffness_nm_rad,
        stop_damping_ratio=0.7,
        counts_per_rev=hw.encoder_counts,
        encoder_on_link=True,
        dt_s=0.0005,
    )


class SimOpenArm(StartsOnEnter):
    """One simulated OpenArm v10 arm (8 motors) answering on a CAN channel, on a simulated clock.

    Args:
        channel: python-can channel (``virtual``: a name unique to this arm).
        side: ``"right"`` or ``"left"``.
        seed: Draws the hidden mounts and factory zeros (and the scenarios' randomness).
        zeroed: The motors hold the zero a perfect calibration writes (reading = joint angle); default a factory
            zero (arbitrary).
        scenarios: Joint name → what is special about it (a missing stop, a snag, ...; ``sim.scenarios``).
        search_torque_nm: The torque a stop search pushes with, per joint (scales the scenarios; default 40 %
            of the motor's peak).
        clock: Simulated time shared with the host (default a new one).
        interface: python-can interface (``virtual`` by default).
        bus_kwargs: More ``can.Bus`` arguments for the simulator's side of the channel.
        realtime: Move the simulated clock with the wall clock (every 5 ms, integrating every joint), for a
            standalone device whose clients do not sleep on :attr:`clock` (``robocal sim openarm``).
    """

    def __init__(
        self,
        channel: str,
        *,
        side: Side = "right",
        seed: int = 0,
        zeroed: bool = False,
        scenarios: Mapping[str, Scenario] | None = None,
        search_torque_nm: Mapping[str, float] | None = None,
        clock: SimClock | None = None,
        interface: str = "virtual",
        bus_kwargs: dict[str, object] | None = None,
        realtime: bool = False,
    ) -> None:
        self.side: Side = side
        self.realtime = realtime
        self._pacer: RealtimePacer | None = None
        self.joints = openarm_joints(side)
        names = {j.name for j in self.joints}
        unknown = sorted(set(scenarios or {}) - names)
        if unknown:
            raise UsageError(
                f"no joint(s) {', '.join(unknown)} on the OpenArm; known: {', '.join(sorted(names))}"
            )
        self.clock = clock if clock is not None else SimClock()
        rng = np.random.default_rng(seed)
        self.plants: dict[str, JointPlant] = {}
        self.motors: dict[str, SimDamiaoMotor] = {}
        for j in self.joints:
            torque = (search_torque_nm or {}).get(j.name, 0.4 * j.peak_torque_nm)
            plant = make_plant(
                (scenarios or {}).get(j.name, Scenario()),
                _nominal(j),
                search_torque_nm=torque,
                seed=seed * 1000 + j.esc_id,
                q0_rad=j.rest_rad,
            )
            mount = float(rng.uniform(0.0, math.tau))
            factory_zero = float(rng.uniform(0.0, math.tau))
            self.plants[j.name] = plant
            self.motors[j.name] = SimDamiaoMotor(
                j.esc_id,
                j.mst_id,
                j.model,
                mount_rad=mount,
                zero_abs_rad=mount if zeroed else factory_zero,
                plant=plant,
                clock=self.clock,
            )
        self.bus = SimDamiaoBus(channel, self.motors.values(), interface=interface, bus_kwargs=bus_kwargs)
        self.channel = channel

    def start(self) -> SimOpenArm:
        """Start answering on the channel (and, ``realtime``, moving the clock with the wall clock)."""
        self.bus.start()
        if self.realtime:
            lock = self.bus.lock
            self._pacer = RealtimePacer(
                self.clock, self.motors.values(), lambda: lock, name=f"sim-openarm-{self.channel}"
            )
            self._pacer.start()
        return self

    def stop(self) -> None:
        """Stop answering."""
        if self._pacer is not None:
            self._pacer.stop()
            self._pacer = None
        self.bus.stop()

    def motor_specs(self) -> list[DamiaoMotor]:
        """The arm's motors as :class:`~.bus.DamiaoBus` takes them."""
        return [DamiaoMotor(j.name, j.esc_id, j.mst_id, j.model) for j in self.joints]

    def joint_rad(self, name: str) -> float:
        """The true joint angle (the link's), rad."""
        return self.plants[self._joint(name).name].link_rad

    def joint_angles_rad(self) -> dict[str, float]:
        """Every true joint angle, rad."""
        with self.bus.lock:
            return {j.name: self.plants[j.name].link_rad for j in self.joints}

    def set_joint(self, name: str, q_rad: float) -> None:
        """Put a joint somewhere by hand (the motor's multi-turn count follows; nothing else changes)."""
        with self.bus.lock:
            self.motors[self._joint(name).name].set_position(q_rad)

    def zero_error_rad(self, name: str) -> float:
        """How far the motor's zero is from the joint's 0, rad (0 after a perfect calibration)."""
        m = self.motors[self._joint(name).name]
        with self.bus.lock:
            return m.reading_rad(m.joint_rad()) - m.joint_rad()

    def silence(self, name: str, silent: bool = True) -> None:
        """Make a motor stop answering (its frames are not heard either: power or cable lost), or answer again."""
        esc = self._joint(name).esc_id
        with self.bus.lock:
            if silent:
                self.bus.silent.add(esc)
            else:
                self.bus.silent.discard(esc)

    def inject_fault(self, name: str, code: State) -> None:
        """Latch an error state in a motor (0x8-0xE): it goes limp and reports ``code`` until cleared (0xFB)."""
        with self.bus.lock:
            self.motors[self._joint(name).name].inject_fault(code)

    def power_cycle(self) -> None:
        """Switch every motor off and on: RAM from flash, disabled, readings within ±π of the stored zero."""
        with self.bus.lock:
            for m in self.motors.values():
                m.power_on()

    def _joint(self, name: str) -> OpenArmJoint:
        for j in self.joints:
            if j.name == name:
                return j
        raise UsageError(f"no joint {name!r} on the OpenArm; known: {', '.join(j.name for j in self.joints)}")
