"""A simulated Lite bimanual robot (14 Robstride joints on two ``virtual`` CAN channels) and its operator.

The joint table (ids, buses, models, directions, limits) is the Lite bimanual one (Humanoid-Control
``hardware_specs`` / Lite-Description ``ros2_control.json``): left arm ids 11–17 on ``can0``, right arm ids
21–27 on ``can1``. Each motor gets a hidden random factory zero (from the seed), a random power-on pose and
optional encoder noise. A :class:`SimOperator` moves the joints by hand: during a sweep it pushes each joint
into its lower and upper hard stop; it can skip a joint or stop short, and it answers the guided direction
check by moving a joint toward its + limit. Simulated time advances one tick per :meth:`SimLite.step`, so a
sweep runs as fast as the CAN round trips allow.
"""

from __future__ import annotations

import contextlib
import itertools
import math
import os
import threading
import time
from collections.abc import Iterable, Iterator, Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from ...core.lifecycle import StartsOnEnter
from ...errors import UsageError
from ..robstride.protocol import CommType
from ..robstride.sim import SimMotor, SimMotorBus
from .lite_physics import lite_plant_params
from .operator import JointView
from .pacer import RealtimePacer
from .physics import SimClock
from .scenarios import Scenario, make_plant

__all__ = ["LITE_JOINTS", "LiteHands", "LiteJoint", "SimLite", "SimOperator", "lite_urdf_text"]


@dataclass(frozen=True)
class LiteJoint:
    """One row of the Lite bimanual joint table (limits in rad, torque N·m, current A)."""

    name: str
    can_id: int
    bus: str
    model: str
    direction: int
    lower: float
    upper: float
    torque_limit: float
    current_limit: float


LITE_JOINTS: tuple[LiteJoint, ...] = (
    LiteJoint("left_shoulder_pitch", 11, "can0", "rs-02", -1, -3.142, 0.785, 17, 27),
    LiteJoint("left_shoulder_roll", 12, "can0", "rs-00", -1, -1.571, 1.920, 14, 16),
    LiteJoint("left_shoulder_yaw", 13, "can0", "rs-00", 1, -1.571, 1.571, 14, 16),
    LiteJoint("left_elbow_pitch", 14, "can0", "rs-00", -1, -2.356, 0.000, 14, 16),
    LiteJoint("left_wrist_yaw", 15, "can0", "rs-05", 1, -1.571, 1.571, 4, 14),
    LiteJoint("left_wrist_roll", 16, "can0", "rs-05", -1, -0.698, 0.698, 4, 14),
    LiteJoint("left_wrist_pitch", 17, "can0", "rs-05", -1, -0.785, 0.785, 4, 14),
    LiteJoint("right_shoulder_pitch", 21, "can1", "rs-02", 1, -3.142, 0.785, 17, 27),
    LiteJoint("right_shoulder_roll", 22, "can1", "rs-00", -1, -1.920, 1.571, 14, 16),
    LiteJoint("right_shoulder_yaw", 23, "can1", "rs-00", 1, -1.571, 1.571, 14, 16),
    LiteJoint("right_elbow_pitch", 24, "can1", "rs-00", 1, -2.356, 0.000, 14, 16),
    LiteJoint("right_wrist_yaw", 25, "can1", "rs-05", 1, -1.571, 1.571, 4, 14),
    LiteJoint("right_wrist_roll", 26, "can1", "rs-05", 1, -0.698, 0.698, 4, 14),
    LiteJoint("right_wrist_pitch", 27, "can1", "rs-05", -1, -0.785, 0.785, 4, 14),
)
"""The Lite bimanual joints in URDF order."""

_instances = itertools.count()


class SimOperator:
    """A simulated person moving the joints by hand (joint frame, simulated time).

    Args:
        robot: The robot whose joints are moved.
        speed_rad_s: Hand speed.
        overshoot_rad: How far past a stop the hand pushes (the stop holds the joint).
        dwell_ticks: Ticks spent pressing against each stop.
        skip: Joints never moved during the sweep.
        short_rad: Joint → how far before the upper stop the hand turns back.
    """

    def __init__(
        self,
        robot: SimLite,
        *,
        speed_rad_s: float = 4.0,
        overshoot_rad: float = 0.2,
        dwell_ticks: int = 5,
        skip: Iterable[str] = (),
        short_rad: Mapping[str, float] | None = None,
    ) -> None:
        self.robot = robot
        self.speed_rad_s = speed_rad_s
        self.overshoot_rad = overshoot_rad
        self.dwell_ticks = dwell_ticks
        self.skip = set(skip)
        self.short_rad = dict(short_rad or {})
        self._plans: dict[str, list[float]] = {}
        self._dwell: dict[str, int] = {}
        self.sweep_started = False

    def _hold(self, target: float) -> list[float]:
        return [target] * self.dwell_ticks

    def begin_sweep(self) -> None:
        """Plan the sweep: every joint not skipped goes to its lower stop, its upper stop, then the middle."""
        self.sweep_started = True
        for name, motor in self.robot.motors.items():
            if name in self.skip:
                continue
            lo = motor.stop_lower_rad - self.overshoot_rad
            up = motor.stop_upper_rad + self.overshoot_rad
            if name in self.short_rad:
                up = motor.stop_upper_rad - self.short_rad[name]
            mid = 0.5 * (motor.stop_lower_rad + motor.stop_upper_rad)
            self._plans.setdefault(name, []).extend([lo, *self._hold(lo), up, *self._hold(up), mid])

    def move_toward_plus(self, joint: str, distance_rad: float = 0.5) -> None:
        """Answer the guided direction check: move ``joint`` toward its + limit (joint frame)."""
        motor = self.robot.motors[joint]
        start = self._plans[joint][-1] if self._plans.get(joint) else motor.q_rad
        self._plans.setdefault(joint, []).append(min(start + distance_rad, motor.stop_upper_rad))

    @property
    def busy(self) -> bool:
        """True while any joint still has a motion planned."""
        return any(self._plans.values())

    def step(self, dt_s: float) -> None:
        """Advance the hands by ``dt_s`` of simulated time."""
        max_step = self.speed_rad_s * dt_s
        for name, plan in self._plans.items():
            motor = self.robot.motors[name]
            if not plan:
                motor.set_position(motor.q_rad, 0.0)
                continue
            target = plan[0]
            # the hand position may be past the stop; the joint stays at the stop
            hand = self.robot.hand_rad.get(name, motor.q_rad)
            delta = target - hand
            if abs(delta) <= max_step:
                hand = target
                plan.pop(0)
            else:
                hand += math.copysign(max_step, delta)
            self.robot.hand_rad[name] = hand
            before = motor.q_rad
            motor.set_position(hand)
            motor.v_rad_s = (motor.q_rad - before) / dt_s if dt_s > 0 else 0.0


class SimLite(StartsOnEnter):
    """The simulated Lite bimanual robot: 14 :class:`SimMotor` on two :class:`SimMotorBus` channels.

    Args:
        seed: Seed of the factory zeros, power-on pose and noise.
        noise_rad: Encoder noise (standard deviation), rad.
        flip: Joints whose motor is wired opposite to the URDF ``direction`` (a wrong URDF).
        stop_shift_rad: Joint → (lower, upper) shift of the hard stops from the URDF limits, rad.
        zero_sta: Power-on range of every motor (0: ``[0, 2π)``, 1: ``[−π, π)``, the default here: the
            simulated factory zeros lie within ±1 rad of the joint zeros, as after an assembly-time set-zero).
        single_turn: Report positions wrapped into the power-on range (see :class:`SimMotor`).
        factory_zero_rad: Joint → factory zero overriding the random one.
        silent: Joints whose motor never answers.
        channel_prefix: Prefix of the two ``virtual`` channel names (unique per instance by default).
        dt_s: Simulated time per tick.
        interface: python-can interface of the two buses (``virtual`` by default; ``socketcan`` or
            ``udp_multicast`` to serve other processes, see ``robocal sim lite``).
        channels: The channel of ``can0`` and ``can1`` (required with any interface but ``virtual``).
        physics_cap_nm: Give every joint the physics of ``sim:lite``'s ``--auto`` (a
            :class:`~.physics.JointPlant` its MIT commands move, :mod:`.lite_physics`), in real time: joint → the
            search torque the plant's friction is scaled to (joints not named: 1 N·m). None: no plant, the joints
            move only by hand (the operator-driven Lite of the hand sweep).
    """

    def __init__(
        self,
        seed: int = 0,
        *,
        noise_rad: float = 3e-4,
        flip: Iterable[str] = (),
        stop_shift_rad: Mapping[str, tuple[float, float]] | None = None,
        zero_sta: int = 1,
        single_turn: bool = False,
        factory_zero_rad: Mapping[str, float] | None = None,
        silent: Iterable[str] = (),
        channel_prefix: str | None = None,
        dt_s: float = 0.01,
        skip: Iterable[str] = (),
        short_rad: Mapping[str, float] | None = None,
        interface: str = "virtual",
        channels: Mapping[str, str] | None = None,
        physics_cap_nm: Mapping[str, float] | None = None,
    ) -> None:
        self.seed = seed
        self.dt_s = dt_s
        self.t_s = 0.0
        self.interface = interface
        prefix = channel_prefix or f"robocal-sim-lite-{os.getpid()}-{next(_instances)}"
        self.channels = {"can0": f"{prefix}-can0", "can1": f"{prefix}-can1"}
        if channels is not None:
            if set(channels) != {"can0", "can1"} or channels["can0"] == channels["can1"]:
                raise UsageError("the simulated Lite needs two different channels, for can0 and can1")
            self.channels = dict(channels)
        rng = np.random.default_rng(seed)
        flip = set(flip)
        shifts = dict(stop_shift_rad or {})
        zeros = dict(factory_zero_rad or {})
        self.joints = LITE_JOINTS
        # real time: the clock starts at the monotonic clock, so its times (last_rx_s, watchdog trips) compare with it
        self.clock: SimClock | None = SimClock(time.monotonic()) if physics_cap_nm is not None else None
        self.motors: dict[str, SimMotor] = {}
        self.hand_rad: dict[str, float] = {}
        for j in LITE_JOINTS:
            fz = float(rng.uniform(-1.0, 1.0))
            margin = min(0.6, 0.25 * (j.upper - j.lower))
            q0 = float(rng.uniform(j.lower + margin, j.upper - margin))
            dlo, dup = shifts.get(j.name, (0.0, 0.0))
            physics: dict[str, Any] = {}
            if physics_cap_nm is not None:  # the plant holds the joint at its stops; the encoder noise is its own
                cap = physics_cap_nm.get(j.name, 1.0)
                nominal = lite_plant_params(j.model, j.lower + dlo, j.upper + dup, cap)
                physics = {
                    "plant": make_plant(Scenario(), nominal, search_torque_nm=cap, seed=seed * 1000 + j.can_id,
                                        q0_rad=q0),
                    "clock": self.clock,
                    "latency_s": 0.0,  # the pacer moves the clock with the wall clock
                }  # fmt: skip
            self.motors[j.name] = SimMotor(
                can_id=j.can_id,
                model=j.model,
                direction=-j.direction if j.name in flip else j.direction,
                factory_zero_rad=zeros.get(j.name, fz),
                stop_lower_rad=j.lower + dlo,
                stop_upper_rad=j.upper + dup,
                noise_rad=0.0 if physics else noise_rad,
                zero_sta=zero_sta,
                single_turn=single_turn,
                q_rad=q0,
                seed=seed * 1000 + j.can_id,
                **physics,
            )
        silent_ids = {self.motors[n].can_id for n in silent}
        self.buses = {
            bus: SimMotorBus(
                ch,
                [self.motors[j.name] for j in LITE_JOINTS if j.bus == bus],
                silent=silent_ids,
                interface=interface,
            )
            for bus, ch in self.channels.items()
        }
        self.operator = SimOperator(self, skip=skip, short_rad=short_rad)
        self.pacer: RealtimePacer | None = None
        if self.clock is not None:
            self.pacer = RealtimePacer(self.clock, self.motors.values(), self._both_locks, name="sim-lite-pacer")

    @contextlib.contextmanager
    def _both_locks(self) -> Iterator[None]:
        with self.buses["can0"].lock, self.buses["can1"].lock:
            yield

    def start(self) -> SimLite:
        """Start answering on both channels (both or neither: a failure closes the first); with physics, pace."""
        started: list[SimMotorBus] = []
        try:
            for b in self.buses.values():
                b.start()
                started.append(b)
        except BaseException:
            for b in started:
                b.stop()
            raise
        if self.pacer is not None:
            self.pacer.start()
        return self

    def stop(self) -> None:
        """Stop pacing and both channels."""
        if self.pacer is not None:
            self.pacer.stop()
        for b in self.buses.values():
            b.stop()

    def step(self) -> None:
        """Advance simulated time by one tick (the operator's hands move)."""
        with self.buses["can0"].lock, self.buses["can1"].lock:
            self.operator.step(self.dt_s)
        self.t_s += self.dt_s

    def power_cycle(self) -> None:
        """Power every motor off and on (readings restart inside one turn)."""
        with self.buses["can0"].lock, self.buses["can1"].lock:
            for m in self.motors.values():
                m.power_on()

    def true_offsets(self) -> dict[str, float]:
        """Joint → the homing offset that is true for the current power-on (motor frame, rad)."""
        return {n: m.true_homing_offset_rad for n, m in self.motors.items()}

    def joint_positions(self) -> dict[str, float]:
        """Joint → true joint position, rad."""
        return {n: m.q_rad for n, m in self.motors.items()}


class LiteHands:
    """The hand-movable view of a :class:`SimLite` in real time (a ``HandDevice``; positions in rad, joint frame).

    A motor counts as holding its joint ("torque on") while enabled with a non-zero stiffness, damping or
    feed-forward torque in its last MIT command; zero-torque polling (what ``robocal sweep`` does) leaves the
    joints free.
    """

    unit = "rad"
    step = 0.05

    def __init__(self, robot: SimLite) -> None:
        self.robot = robot
        self.lock = threading.RLock()
        self._last: dict[str, tuple[float, float]] = {}
        self._bus_of = {j.name: j.bus for j in LITE_JOINTS}

    def joint_names(self) -> Sequence[str]:
        """The 14 joints in URDF order."""
        return [j.name for j in LITE_JOINTS]

    def view(self, name: str) -> JointView:
        """One joint: position, stops, torque, the motor's reading, its last command, CAN id."""
        m = self.robot.motors[name]
        cmd = m.last_command
        torque = m.mode == 2 and cmd is not None and any(abs(x) > 0 for x in cmd[2:])
        last = ""
        if cmd is not None:
            last = "MIT p={:+.3f} v={:+.2f} kp={:g} kd={:g} t={:+.2f}".format(*cmd)
        return JointView(
            name=name,
            position=m.q_rad,
            low=m.stop_lower_rad,
            high=m.stop_upper_rad,
            mid=0.5 * (m.stop_lower_rad + m.stop_upper_rad),
            torque=torque,
            reading=m.reading_rad(noisy=False),
            last_write=last,
            last_write_age_s=None,
            extra={
                "can_id": m.can_id,
                "bus": self._bus_of[name],
                "enabled": m.mode == 2,
                "can_timeout": m.can_timeout,
                "last_rx_s": m.last_rx_s,
                "watchdog_trips": [list(t) for t in m.watchdog_trips],
            },
        )

    def reads(self, name: str) -> int:
        """Requests the motor answered with its feedback (position) so far: MIT, enable, stop."""
        requests = self.robot.motors[name].requests
        return sum(requests.get(c, 0) for c in (CommType.MIT, CommType.ENABLE, CommType.STOP))

    def place(self, name: str, position: float) -> None:
        """Move the joint (the stops hold it); its velocity follows from the previous placement."""
        now = time.monotonic()
        m = self.robot.motors[name]
        with self.robot.buses[self._bus_of[name]].lock:
            t0, placed = self._last.get(name, (now, m.q_rad))  # the hand's own speed, not a drift's
            m.set_position(position)
            dt = now - t0
            m.v_rad_s = (m.q_rad - placed) / dt if 0 < dt < 0.5 else 0.0
        self._last[name] = (now, m.q_rad)


def lite_urdf_text() -> str:
    """A minimal URDF of the Lite bimanual arms with ``<ros2_control>`` joint params (for the demo)."""
    links = ['  <link name="base_link"/>']
    for side in ("left", "right"):
        parent = "base_link"
        for j in (j for j in LITE_JOINTS if j.name.startswith(side)):
            links.append(f'  <link name="{j.name}_link"/>')
            links.append(
                f'  <joint name="{j.name}" type="revolute"><parent link="{parent}"/>'
                f'<child link="{j.name}_link"/><axis xyz="0 1 0"/>'
                f'<limit lower="{j.lower}" upper="{j.upper}" effort="{j.torque_limit}" velocity="30"/>'
                "</joint>"
            )
            parent = f"{j.name}_link"
    systems = []
    for bus in ("can0", "can1"):
        rows = [f'  <ros2_control name="RobstrideSystem_{bus}" type="system">', "    <hardware>"]
        rows.append(f'      <param name="can_interface">{bus}</param>')
        rows.append("    </hardware>")
        for j in (j for j in LITE_JOINTS if j.bus == bus):
            rows.append(f'    <joint name="{j.name}">')
            for key, value in (
                ("can_id", j.can_id),
                ("model", j.model),
                ("direction", j.direction),
                ("lower_limit", j.lower),
                ("upper_limit", j.upper),
            ):
                rows.append(f'      <param name="{key}">{value}</param>')
            rows.append("    </joint>")
        rows.append("  </ros2_control>")
        systems.extend(rows)
    body = "\n".join(links + systems)
    return f'<?xml version="1.0"?>\n<robot name="lite_bimanual">\n{body}\n</robot>\n'
