"""Runtime read/write of a calibrated Robstride robot, in the joint frame.

:class:`CalibratedRobot` is built from the URDF (directions, limits, ids, models), a calibration file (homing
offsets) and the CAN buses. :meth:`CalibratedRobot.read` returns joint-frame position, velocity and effort
for every joint in one call; :meth:`CalibratedRobot.write` takes joint-frame MIT targets and sends motor-frame
frames (position through the full map, velocity and feed-forward torque through the direction only, gains
unchanged). The first read after power-on picks, per joint, the 2π branch that puts the joint inside its
limits (:meth:`robocal.core.RobotCalibration.unwrap_to_limits`) and keeps that shift for later ticks.

Later reads follow the ±4π wrap of the type-2 position: a sample-to-sample jump of more than 4π (half the 8π
period) is a wrap, and whole 8π turns are added so the joint position stays continuous over long runs.
:meth:`CalibratedRobot.write` sends positions in the motor's own counting frame (the reading's), so a target
just past the wrap is clamped to ±4π by the encoder instead of landing on the far side of the wrap.
"""

from __future__ import annotations

import contextlib
import math
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt

from ...backends.robstride.joint_driver import WATCHDOG_S, RobstrideWatchdogError
from ...backends.robstride.protocol import model_limits
from ...backends.sources import RobstrideSource, open_source, parse_source
from ...core.arrays import FloatArray
from ...core.jointmap import RobotCalibration
from ...core.lifecycle import ClosesOnExit
from ...errors import CalibError, JointMismatchError, ShapeMismatchError, UsageError
from .joint_specs import joint_calibration, read_joints

__all__ = ["FEEDBACK_WRAP_PERIOD_RAD", "CalibratedRobot", "JointState", "open_robot"]

FEEDBACK_WRAP_PERIOD_RAD = 8.0 * math.pi
"""Period of the type-2 feedback position, which loops within ±4π, rad."""


@dataclass(frozen=True)
class JointState:
    """Joint-frame state of every joint, shape ``(N,)`` each.

    Attributes:
        position_rad: Joint positions, rad.
        velocity_rad_s: Joint velocities, rad/s.
        effort_nm: Joint efforts, N·m.
    """

    position_rad: FloatArray
    velocity_rad_s: FloatArray
    effort_nm: FloatArray


class CalibratedRobot(ClosesOnExit):
    """Joint-frame read/write over Robstride buses.

    Args:
        calibration: Joint maps in URDF order (directions from the URDF, offsets from the file).
        lower: Lower limits, shape ``(N,)``, rad.
        upper: Upper limits, shape ``(N,)``, rad.
        source: The open Robstride source (its buses are used; it is closed by :meth:`close`).
    """

    def __init__(
        self, calibration: RobotCalibration, lower: FloatArray, upper: FloatArray, source: RobstrideSource
    ) -> None:
        if tuple(source.joint_names) != calibration.joint_names:
            raise JointMismatchError("robot: the buses' joints do not match the calibration's joint order")
        self.calibration = calibration
        self.joint_names = calibration.joint_names
        self.lower = np.asarray(lower, dtype=np.float64)
        self.upper = np.asarray(upper, dtype=np.float64)
        self.source = source
        self._shift_rad: FloatArray | None = None  # whole turns added on the first read after power-on
        self._wrap_rad = np.zeros(len(self.joint_names))  # whole 8π loops of the ±4π feedback since then
        self._last_raw = np.full(len(self.joint_names), np.nan)  # last finite raw reading per joint
        self._index = {name: i for i, name in enumerate(self.joint_names)}
        self._held: list[dict[str, tuple[float, float, float, float, float]]] | None = None  # per bus
        self._enabled = False
        self._watchdog_before: dict[tuple[int, str], float] = {}  # (bus, motor) → canTimeout before enable, s
        # per-tick constants, computed once: which array slot each bus's motor fills, and the gain limits
        self._bus_slots = [[(name, self._index[name]) for name in bus.motors] for bus in source.buses]
        limits = {
            name: model_limits(motor.model) for bus in source.buses for name, motor in bus.motors.items()
        }
        self._limits = [limits[name] for name in self.joint_names]
        self._gain_max = np.array(
            [[lim.kp_max for lim in self._limits], [lim.kd_max for lim in self._limits]]
        )

    @property
    def branch_shift_rad(self) -> FloatArray | None:
        """Raw shift (multiples of 2π) chosen on the first read, shape ``(N,)``; None before it."""
        return None if self._shift_rad is None else self._shift_rad.copy()

    @property
    def wrap_shift_rad(self) -> FloatArray:
        """Raw shift (multiples of 8π) added since the first read for the ±4π feedback wrap, shape ``(N,)``."""
        out: FloatArray = self._wrap_rad.copy()
        return out

    def _to_state(self, raw: FloatArray, vel: FloatArray, eff: FloatArray) -> JointState:
        state = np.empty((3, len(self.joint_names)))
        state[0], state[1], state[2] = raw, vel, eff
        return self._state_to_joint(state)

    def _state_to_joint(self, state: FloatArray) -> JointState:
        """Raw ``(3, N)`` state (rows position, velocity, effort; modified in place) → joint frame."""
        cal = self.calibration
        raw = state[0]
        step = np.abs(raw - self._last_raw).max()  # NaN when a reading (or the last one) is missing
        if self._shift_rad is not None and step < 0.5 * FEEDBACK_WRAP_PERIOD_RAD:
            self._last_raw = raw.copy()  # the common tick: every joint read, no loop (same as below, cheaper)
        else:
            if self._shift_rad is None:
                self._shift_rad = cal.unwrap_to_limits(raw, self.lower, self.upper) - raw
            else:  # follow the ±4π loop sample to sample (a joint with no reading keeps its last one)
                loops = np.round((raw - self._last_raw) * (1.0 / FEEDBACK_WRAP_PERIOD_RAD))
                if loops.any():  # a loop, or a NaN (NaN is truthy)
                    loops[np.isnan(loops)] = 0.0
                    self._wrap_rad -= FEEDBACK_WRAP_PERIOD_RAD * loops
            finite = np.isfinite(raw)
            self._last_raw = raw.copy() if finite.all() else np.where(finite, raw, self._last_raw)
        raw += self._shift_rad
        raw += self._wrap_rad
        q, v, e = cal.state_to_joint(state, out=state)  # one fused map for all three rows
        return JointState(q, v, e)

    def read(self) -> JointState:
        """Poll every joint and return the joint-frame state.

        Before the first :meth:`write` the poll is the passive zero-torque MIT frame; afterwards it repeats the
        last targets written, so reading never drops the gains or the feed-forward torque of a running loop.
        """
        if self._held is None:
            s = self.source.read()
            assert s.velocity_rad_s is not None and s.effort_nm is not None
            return self._to_state(s.position_rad, s.velocity_rad_s, s.effort_nm)
        return self._send(self._held)

    def _send(self, commands: list[dict[str, tuple[float, float, float, float, float]]]) -> JointState:
        n = len(self.joint_names)
        pos, vel, eff = [math.nan] * n, [math.nan] * n, [math.nan] * n  # lists: cheaper to fill than arrays
        index = self._index
        for bus, cmds in zip(self.source.buses, commands, strict=True):
            feedback = bus.mit_many(cmds)
            if self._enabled:
                self._check_run_mode(feedback)
            for name, fb in feedback.items():
                i = index[name]
                pos[i], vel[i], eff[i] = fb.position_rad, fb.velocity_rad_s, fb.torque_nm
        return self._state_to_joint(np.array((pos, vel, eff)))

    def write(
        self,
        position_rad: npt.ArrayLike,
        velocity_rad_s: npt.ArrayLike = 0.0,
        kp: npt.ArrayLike = 0.0,
        kd: npt.ArrayLike = 0.0,
        torque_nm: npt.ArrayLike = 0.0,
    ) -> JointState:
        """Send joint-frame MIT targets to every joint and return the joint-frame feedback.

        The targets are held: later :meth:`read` calls repeat them until the next write.

        Args:
            position_rad: Target joint positions, shape ``(N,)``, rad.
            velocity_rad_s: Target joint velocities, shape ``(N,)`` or scalar, rad/s.
            kp: Position gains, shape ``(N,)`` or scalar (unchanged by the calibration).
            kd: Velocity gains, shape ``(N,)`` or scalar (unchanged).
            torque_nm: Feed-forward torques, shape ``(N,)`` or scalar, N·m.

        Returns:
            The state decoded from the replies.
        """
        n = len(self.joint_names)
        if self._shift_rad is None:
            raise UsageError(
                "robot.write before the first robot.read: read once after power-on to pick branches"
            )
        cal = self.calibration
        # rows position, velocity, torque (a (3, N) joint state, mapped in place), kp, kd
        cmd = np.empty((5, n))
        for row, (x, what) in enumerate(
            (
                (position_rad, "position"),
                (velocity_rad_s, "velocity"),
                (torque_nm, "torque"),
                (kp, "kp"),
                (kd, "kd"),
            )
        ):
            if type(x) is float or type(x) is int:  # the common scalar argument: no array to build
                cmd[row] = x
                continue
            try:
                a = np.asarray(x, dtype=np.float64)
            except (TypeError, ValueError):
                raise ShapeMismatchError(
                    f"robot.write: {what} must be {n} finite numbers, got {x!r}"
                ) from None
            if a.ndim != 0 and a.shape != (n,):
                raise ShapeMismatchError(
                    f"robot.write: {what} must be {n} finite numbers, got shape {a.shape}"
                )
            cmd[row] = a
        if not np.isfinite(cmd).all():
            row = int(np.flatnonzero(~np.isfinite(cmd).all(axis=1))[0])
            what = ("position", "velocity", "torque", "kp", "kd")[row]
            raise ShapeMismatchError(f"robot.write: {what} must be {n} finite numbers, got shape ({n},)")
        gains = cmd[3:]
        if not ((gains >= 0.0) & (gains <= self._gain_max)).all():
            kp_v, kd_v = cmd[3], cmd[4]
            bad = (kp_v < 0) | (kp_v > self._gain_max[0]) | (kd_v < 0) | (kd_v > self._gain_max[1])
            i = int(np.flatnonzero(bad)[0])
            lim = self._limits[i]
            raise UsageError(
                f"robot.write: joint {self.joint_names[i]!r} ({lim.name}): kp {kp_v[i]:g} / kd {kd_v[i]:g} "
                f"outside 0..{lim.kp_max:g} / 0..{lim.kd_max:g}"
            )
        state = cmd[:3]  # a view: mapped in place
        cal.state_to_raw(state, out=state)
        p_raw = cmd[0]
        p_raw -= self._shift_rad
        p_raw -= self._wrap_rad
        p, v, t, kp_l, kd_l = cmd.tolist()
        # motor frame (position, velocity, kp, kd, torque) per joint
        rows = list(zip(p, v, kp_l, kd_l, t, strict=True))
        commands = [{name: rows[i] for name, i in slots} for slots in self._bus_slots]
        self._held = commands
        return self._send(self._held)

    def enable(self, watchdog_s: float = WATCHDOG_S) -> JointState:
        """Arm every motor's host-loss watchdog, then enable it (type 3) so that :meth:`write` targets act.

        Read once first (the branch selection needs it); the motors then hold the targets of the next
        :meth:`write` — until then they are sent the passive zero-torque frame. Each motor's ``canTimeout`` is set
        to ``watchdog_s`` first (as ``sweep --auto`` does; 0: left as it is): a motor that hears no frame for that
        long (the program stopped calling :meth:`read`/:meth:`write`, was killed, the cable went) enters reset
        mode on its own. :meth:`disable` (and :meth:`close`) put the previous ``canTimeout`` back.

        Returns:
            The replies' state.
        """
        if watchdog_s > 0:
            for bus in self.source.buses:
                for name in bus.motors:
                    if (id(bus), name) not in self._watchdog_before:
                        self._watchdog_before[(id(bus), name)] = bus.arm_watchdog(name, watchdog_s)
        state = self._each_motor(lambda bus, name: bus.enable(name))
        self._enabled = True
        return state

    def disable(self) -> JointState:
        """Stop every motor (type 4, reset mode): torque off; the watchdogs back as they were before :meth:`enable`.

        Called by :meth:`close` after :meth:`enable`.
        """
        self._held = None
        try:
            state = self._each_motor(lambda bus, name: bus.stop(name))
            self._enabled = False
        finally:
            for bus in self.source.buses:
                for name in bus.motors:
                    before = self._watchdog_before.pop((id(bus), name), None)
                    if before is not None:
                        with contextlib.suppress(CalibError):  # every motor gets its chance
                            bus.disarm_watchdog(name, before)
        return state

    def _check_run_mode(self, feedback: dict[str, Any]) -> None:
        """While enabled, a motor whose reply says it left run mode was stopped by its watchdog (or reset)."""
        left = sorted(name for name, fb in feedback.items() if getattr(fb, "mode", 2) != 2)
        if left:
            self._held = None
            raise RobstrideWatchdogError(
                f"robot: {', '.join(left)} left run mode on its own: the CAN timeout stopped them because no "
                "frame reached them in time (the program paused between reads/writes longer than the watchdog "
                "time, or the bus dropped frames); enable again to go on"
            )

    def _each_motor(self, call: Callable[[Any, str], Any]) -> JointState:
        n = len(self.joint_names)
        raw, vel, eff = np.full(n, np.nan), np.full(n, np.nan), np.full(n, np.nan)
        for bus in self.source.buses:
            for name in bus.motors:
                fb = call(bus, name)
                i = self._index[name]
                raw[i], vel[i], eff[i] = fb.position_rad, fb.velocity_rad_s, fb.torque_nm
        return self._to_state(raw, vel, eff)

    def close(self) -> None:
        """Stop the motors if this object enabled them (their watchdogs put back), then close the buses."""
        try:
            if self._enabled or self._watchdog_before:
                with contextlib.suppress(CalibError):
                    self.disable()
        finally:
            self.source.close()


def open_robot(
    urdf_path: str | Path, calibration_path: str | Path, source: str, *, timeout_s: float = 0.1
) -> CalibratedRobot:
    """Build a :class:`CalibratedRobot` from a URDF, a calibration file and ``sim:lite`` or ``can:…``.

    Raises:
        UsageError: A ``replay:`` source (a recording cannot be commanded).
        JointMismatchError: The calibration lacks a URDF joint.
    """
    spec = parse_source(source)
    if spec.kind == "replay":
        raise UsageError("a robot needs sim: or can: buses, not a replay")
    joints, cf = read_joints(urdf_path, calibration_path)
    missing = [j.name for j in joints if j.name not in cf.calibration]
    if missing:
        raise JointMismatchError(f"calibration {calibration_path}: no offset for {', '.join(missing)}")
    cal = joint_calibration(cf, joints)
    src = open_source(spec, joints, timeout_s=timeout_s)
    assert isinstance(src, RobstrideSource)
    lower = np.array([j.lower for j in joints])
    upper = np.array([j.upper for j in joints])
    return CalibratedRobot(cal, lower, upper, src)
