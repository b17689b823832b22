"""Simulated LeRobot arms (SO-101 and Koch, follower and leader) and a simulated operator.

A :class:`SimArm` puts one :class:`~robocal.backends.sim.servo.SimServo` per motor behind a pseudo-terminal,
with a physical truth per joint (mid pose and hard stops in the motor's actual-tick frame). A
:class:`SimArmOperator` plays the human: it holds the arm at its mid pose when asked and sweeps every joint from
stop to stop during range recording, and can raise ``KeyboardInterrupt`` at a chosen step (Ctrl-C).
"""

from __future__ import annotations

import threading
import time
from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np

from ...core.lerobot import MotorCalibration, RobotSpec
from ...core.lifecycle import StartsOnEnter
from ...errors import UsageError
from .operator import JointView
from .servo import SimServo, SimServoBus

__all__ = ["DEFAULT_TRUTH", "ArmHands", "JointTruth", "SimArm", "SimArmOperator", "seeded_truth"]


@dataclass(frozen=True)
class JointTruth:
    """Physical truth of one joint, in the motor's actual ticks (continuous across the 0/4096 seam).

    Attributes:
        mid_ticks: Where the operator holds the joint for "middle of the range".
        stop_low_ticks: Lower hard stop.
        stop_high_ticks: Upper hard stop.
    """

    mid_ticks: float
    stop_low_ticks: float
    stop_high_ticks: float


def _t(mid: float, lo: float, hi: float) -> JointTruth:
    return JointTruth(mid, lo, hi)


DEFAULT_TRUTH: dict[str, dict[str, JointTruth]] = {
    "so101_follower": {
        "shoulder_pan": _t(2100, 900, 3300),
        "shoulder_lift": _t(1950, 780, 3150),
        "elbow_flex": _t(2000, 850, 3100),
        "wrist_flex": _t(4200, 3100, 5300),  # its travel crosses the encoder seam
        "wrist_roll": _t(2047, 113, 3981),  # not a full turn (huggingface/lerobot#4583)
        "gripper": _t(2300, 2000, 3400),
    },
    "so101_leader": {
        "shoulder_pan": _t(1990, 820, 3210),
        "shoulder_lift": _t(2080, 900, 3260),
        "elbow_flex": _t(1900, 700, 3050),
        "wrist_flex": _t(2150, 1000, 3250),
        "wrist_roll": _t(2010, 200, 3900),
        "gripper": _t(2100, 1900, 2900),
    },
    "koch_follower": {
        "shoulder_pan": _t(2048, 500, 3600),
        "shoulder_lift": _t(1900, 800, 3000),
        "elbow_flex": _t(2100, 1000, 3200),
        "wrist_flex": _t(2000, 900, 3100),
        "wrist_roll": _t(2048, 300, 3800),
        "gripper": _t(2200, 2000, 3000),
    },
    "koch_leader": {
        "shoulder_pan": _t(2000, 600, 3500),
        "shoulder_lift": _t(2050, 900, 3100),
        "elbow_flex": _t(2100, 1050, 3150),
        "wrist_flex": _t(1950, 850, 3050),
        "wrist_roll": _t(2048, 300, 3700),
        "gripper": _t(2150, 1950, 2800),
    },
}
DEFAULT_TRUTH["so100_follower"] = DEFAULT_TRUTH["so101_follower"]  # the same arm to LeRobot
DEFAULT_TRUTH["so100_leader"] = DEFAULT_TRUTH["so101_leader"]
"""Default physical truth of each simulated arm."""


def seeded_truth(
    robot: str,
    seed: int | None,
    *,
    expected_deg: Mapping[str, tuple[float, float]] | None = None,
    stop_spread_deg: float = 4.5,
) -> dict[str, JointTruth]:
    """The physical truth of a simulated arm: :data:`DEFAULT_TRUTH`, or a seeded variation of it.

    Args:
        robot: ``so101_follower``, ``so101_leader``, ``koch_follower`` or ``koch_leader``.
        seed: None for the default truth; otherwise every joint is shifted by up to ±150 ticks and each
            stop moved by up to ±60 ticks, reproducibly for that seed.
        expected_deg: Joint → the (lower, upper) stop angles a robot profile expects (degrees, joint frame).
            With a seed, these joints' stops are drawn from the profile instead: the expected span centred
            where the default stops' middle lands, each stop moved by up to ``stop_spread_deg`` (the same
            seeded draws), so a seeded arm stays inside what the profile says a real arm has.
        stop_spread_deg: The largest deviation of one stop from the profile's angle (≥ 0).

    Returns:
        Joint name → truth (actual ticks).
    """
    if robot not in DEFAULT_TRUTH:
        raise UsageError(f"unknown robot {robot!r}; valid: {', '.join(DEFAULT_TRUTH)}")
    base = DEFAULT_TRUTH[robot]
    if seed is None:
        return dict(base)
    if not stop_spread_deg >= 0:
        raise UsageError(f"stop spread must be ≥ 0°, got {stop_spread_deg!r}")
    expected = dict(expected_deg or {})
    rng = np.random.default_rng(seed)
    per_deg = 4096 / 360.0
    out = {}
    for name, t in base.items():
        shift = int(rng.integers(-150, 151))
        lo_d, hi_d = (int(v) for v in rng.integers(-60, 61, size=2))
        if name in expected:
            lo_deg, hi_deg = expected[name]
            centre = 0.5 * (t.stop_low_ticks + t.stop_high_ticks) + shift
            half = 0.5 * (hi_deg - lo_deg) * per_deg
            spread = stop_spread_deg * per_deg / 60.0
            out[name] = JointTruth(
                t.mid_ticks + shift,
                round(centre - half + lo_d * spread, 1),
                round(centre + half + hi_d * spread, 1),
            )
            continue
        out[name] = JointTruth(
            t.mid_ticks + shift, t.stop_low_ticks + shift + lo_d, t.stop_high_ticks + shift + hi_d
        )
    return out


class SimArm(StartsOnEnter):
    """A simulated LeRobot arm on a pseudo-terminal (or an in-process port).

    Args:
        robot: The arm (its robot profile's :class:`RobotSpec`, e.g.
            ``robocal.workflows.lerobot.robot_spec("so101_follower")``): one servo per motor, with its id
            and model.
        truth: Per-joint physical truth; default :data:`DEFAULT_TRUTH` of the arm's name.
        noise_ticks: Read noise (±ticks) on Present_Position.
        seed: Noise seed.
        eeprom: Initial EEPROM per motor name (``Homing_Offset``, ``Min_Position_Limit``, ... ), e.g. a
            previous calibration.
        factory: Servos as shipped: every one at id 1 and the vendor's default baud rate, no calibration
            (for LeRobot's ``setup_motors``; plug them in one at a time with :meth:`SimServoBus.attach`).
        transport: ``"pty"`` (a pseudo-terminal, as a real arm) or ``"inproc"`` (the same packets through an
            in-process port, :attr:`port` ``inproc://…``: no pty, no thread; for fast simulation).
    """

    def __init__(
        self,
        robot: RobotSpec,
        *,
        truth: Mapping[str, JointTruth] | None = None,
        noise_ticks: int = 0,
        seed: int = 0,
        eeprom: Mapping[str, Mapping[str, int]] | None = None,
        factory: bool = False,
        transport: str = "pty",
    ) -> None:
        if not isinstance(robot, RobotSpec):
            raise UsageError(f"SimArm takes the arm's RobotSpec (robot_spec({robot!r})), not {type(robot).__name__}")
        if truth is None and robot.name not in DEFAULT_TRUTH:
            raise UsageError(
                f"no simulated truth for robot {robot.name!r}: the simulator has {', '.join(sorted(DEFAULT_TRUTH))} "
                "(from Python, pass truth=)"
            )
        self.spec: RobotSpec = robot
        self.truth: dict[str, JointTruth] = dict(truth if truth is not None else DEFAULT_TRUTH[robot.name])
        servos = []
        for m in self.spec.motors:
            t = self.truth[m.name]
            servo = SimServo(
                m.motor_id, m.model, float(t.mid_ticks), float(t.stop_low_ticks), float(t.stop_high_ticks)
            )
            if factory:
                servo.factory_reset()
            for reg, value in (eeprom or {}).get(m.name, {}).items():
                servo.set_reg(reg, value)
            servos.append(servo)
        self.bus = SimServoBus(servos, noise_ticks=noise_ticks, seed=seed, transport=transport)
        self.port = self.bus.port

    def start(self) -> SimArm:
        """Start the simulated bus."""
        self.bus.start()
        return self

    def stop(self) -> None:
        """Stop the simulated bus and close the pty."""
        self.bus.stop()

    def servo(self, name: str) -> SimServo:
        """The simulated servo of a motor."""
        return self.bus.servos[self.spec.motors[self.spec.motor_names.index(name)].motor_id]

    def eeprom(self) -> dict[str, dict[str, int]]:
        """Calibration EEPROM registers per motor name."""
        snap = self.bus.snapshot()
        return {m.name: snap[m.motor_id] for m in self.spec.motors}

    def move(self, positions: Mapping[str, float]) -> None:
        """Move joints by hand (actual ticks)."""
        self.bus.move({self.servo(n).motor_id: p for n, p in positions.items()})

    def recovered_stops(self, cals: Mapping[str, MotorCalibration]) -> dict[str, tuple[int, int]]:
        """Hard stops implied by a calibration, mapped back to actual ticks (modulo a turn on Feetech)."""
        out: dict[str, tuple[int, int]] = {}
        rule = self.spec.homing
        hardware_drive_mode = self.spec.vendor_spec.drive_mode_in_hardware
        for name, c in cals.items():
            sign = -1 if (hardware_drive_mode and c.drive_mode) else 1
            a = sign * (c.range_min - rule.offset_sign * c.homing_offset)
            b = sign * (c.range_max - rule.offset_sign * c.homing_offset)
            out[name] = (min(a, b), max(a, b))
        return out


class ArmHands:
    """The hand-movable view of a :class:`SimArm` (a :class:`~robocal.backends.sim.operator.HandDevice`).

    Positions are actual ticks (the frame of the hard stops).
    """

    unit = "ticks"
    step = 20.0

    def __init__(self, arm: SimArm) -> None:
        self.arm = arm
        self.lock: threading.RLock = arm.bus.lock

    def joint_names(self) -> Sequence[str]:
        """The arm's motors in LeRobot's order."""
        return self.arm.spec.motor_names

    def view(self, name: str) -> JointView:
        """One joint: physical position, stops, torque, Present_Position, last client write, id/baud."""
        servo = self.arm.servo(name)
        t = self.arm.truth[name]
        return JointView(
            name=name,
            position=servo.actual_ticks,
            low=t.stop_low_ticks,
            high=t.stop_high_ticks,
            mid=t.mid_ticks,
            torque=bool(servo.get_reg("Torque_Enable")),
            reading=float(servo.present_ticks()),
            last_write=servo.last_write,
            last_write_age_s=(time.monotonic() - servo.last_write_time) if servo.last_write else None,
            extra={
                "id": servo.bus_id,
                "baudrate": servo.baudrate,
                "attached": servo.attached,
                **servo.eeprom_snapshot(),
                **(
                    {
                        "Bus_Watchdog": servo.get_reg("Bus_Watchdog"),
                        "Goal_Position": servo.get_reg("Goal_Position"),
                        "watchdog_rx_s": servo.watchdog_rx_s,
                        "watchdog_trips": [list(t) for t in servo.watchdog_trips],
                    }
                    if "Bus_Watchdog" in servo.table
                    else {}
                ),
            },
        )

    def place(self, name: str, position: float) -> None:
        """Put the shaft at ``position`` actual ticks; the hard stops hold it."""
        self.arm.servo(name).move_to(position)

    def reads(self, name: str) -> int:
        """Reads of the servo's ``Present_Position`` answered so far."""
        return self.arm.servo(name).position_reads


class SimArmOperator:
    """Plays the human during calibration: mid pose on request, stop-to-stop sweeps, optional Ctrl-C.

    Args:
        arm: The simulated arm.
        steps_per_segment: Readings per sweep segment (mid → low stop → high stop → mid).
        mid_pose: Override of where joints are held for "middle" (actual ticks), e.g. a poor mid pose.
        interrupt_at_step: Raise ``KeyboardInterrupt`` at this sweep step (simulated Ctrl-C).
        interrupt_at_prompt: Raise ``KeyboardInterrupt`` when this prompt stage is shown.
        overshoot_ticks: How far past each stop the operator pushes (the hard stop holds the joint).
        poses: Extra poses per prompt stage (e.g. the legacy ``"zero"`` and ``"rotated"`` poses), actual ticks.
    """

    def __init__(
        self,
        arm: SimArm,
        *,
        steps_per_segment: int = 8,
        mid_pose: Mapping[str, float] | None = None,
        interrupt_at_step: int | None = None,
        interrupt_at_prompt: str | None = None,
        overshoot_ticks: float = 40.0,
        poses: Mapping[str, Mapping[str, float]] | None = None,
    ) -> None:
        self.poses = {k: dict(v) for k, v in (poses or {}).items()}
        self.arm = arm
        self.steps_per_segment = steps_per_segment
        self.mid_pose = {n: float(t.mid_ticks) for n, t in arm.truth.items()}
        self.mid_pose.update(mid_pose or {})
        self.interrupt_at_step = interrupt_at_step
        self.interrupt_at_prompt = interrupt_at_prompt
        self.overshoot_ticks = overshoot_ticks
        self.step = 0
        self.prompts: list[str] = []

    def prompt(self, stage: str, message: str) -> None:
        """Answer a prompt: at ``"middle"`` hold every joint at its mid pose, then 'press ENTER'."""
        self.prompts.append(stage)
        if stage == self.interrupt_at_prompt:
            raise KeyboardInterrupt
        if stage in self.poses:
            self.arm.move(self.poses[stage])
        elif stage == "middle":
            self.arm.move(self.mid_pose)
            self.step = 0

    def _path(self, name: str, k: int) -> float:
        t = self.arm.truth[name]
        n = self.steps_per_segment
        lo, hi, mid = (
            t.stop_low_ticks - self.overshoot_ticks,
            t.stop_high_ticks + self.overshoot_ticks,
            self.mid_pose[name],
        )
        seg, f = divmod(k, n)
        frac = f / n
        if seg == 0:
            return mid + (lo - mid) * frac
        if seg == 1:
            return lo + (hi - lo) * frac
        if seg == 2:
            return hi + (mid - hi) * frac
        return mid

    def sweep_step(self) -> bool:
        """Move every joint one step along its sweep; True once the sweep is finished ('ENTER')."""
        if self.interrupt_at_step is not None and self.step >= self.interrupt_at_step:
            raise KeyboardInterrupt
        self.step += 1
        self.arm.move({n: self._path(n, self.step) for n in self.arm.truth})
        return self.step > 3 * self.steps_per_segment
