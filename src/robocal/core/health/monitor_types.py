"""The live monitor's values: its configuration (stops, speeds, pairing) and the flags it raises.

Pure Python and numpy; frozen dataclasses built once before a control loop starts.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from numbers import Integral, Real
from typing import Any, TypeAlias

import numpy as np
from numpy.typing import NDArray

from ...errors import UsageError

__all__ = [
    "FLAG_KINDS",
    "HealthFlag",
    "JointFlags",
    "JointNames",
    "JointValues",
    "MonitorConfig",
    "monitor_config",
]

JointNames: TypeAlias = Sequence[str] | NDArray[np.str_]
"""Joint names: a list or tuple of str, or a numpy array of them (not one str)."""

JointValues: TypeAlias = (
    float | np.floating[Any] | Sequence[float] | NDArray[np.floating[Any]] | NDArray[np.integer[Any]]
)
"""One number for every joint, or one per joint (a list, a tuple or a 1-D numpy array; not a str)."""

JointFlags: TypeAlias = bool | np.bool_ | Sequence[bool] | NDArray[np.bool_]
"""One flag for every joint, or one per joint (a list, a tuple or a 1-D numpy bool array; not a str)."""

FLAG_KINDS = ("outside_stops", "step", "wrong_branch", "pinned")
"""What a :class:`HealthFlag` reports:

* ``outside_stops``: a reading past the joint's stops by more than the margin (on no other 2π branch inside);
* ``step``: a change of reading that neither the joint's speed and acceleration nor the commanded motion explain
  (an encoder zero lost, a horn that jumped a tooth, a glitch);
* ``wrong_branch``: a reading a whole turn (2π·k) away from where the joint can be: outside the stops with a
  branch inside them, or a step of 2π·k (a multi-turn Robstride reading on the wrong branch);
* ``pinned``: a follower that stays still, far from its leader, while the leader goes on (the follower is held
  at a stop or by an obstacle: an offset between the two calibrations at a range end, or a blocked joint).
"""

DEG = math.pi / 180.0


@dataclass(frozen=True)
class HealthFlag:
    """One thing the monitor found, on one joint at one tick.

    Attributes:
        t_s: Time of the tick that raised it, s (the caller's clock).
        joint: Joint name.
        kind: One of :data:`FLAG_KINDS`.
        value_rad: ``outside_stops`` / ``wrong_branch`` (outside): the reading, rad; ``step`` / ``wrong_branch``
            (a jump): the unexplained part of the change, rad; ``pinned``: leader − follower, rad.
        limit_rad: The bound it broke: the stop (± margin) for ``outside_stops``, the allowed change for a step,
            the residual threshold for ``pinned``, rad.
    """

    t_s: float
    joint: str
    kind: str
    value_rad: float
    limit_rad: float

    @property
    def message(self) -> str:
        """One line naming the joint, what happened and the degrees."""
        v, lim = math.degrees(self.value_rad), math.degrees(self.limit_rad)
        if self.kind == "outside_stops":
            return f"{self.joint}: reading {v:+.2f}° is past its stop ({lim:+.2f}° with the margin)"
        if self.kind == "wrong_branch":
            return f"{self.joint}: reading {v:+.2f}° is on the wrong 2π branch (a whole turn off)"
        if self.kind == "step":
            return (
                f"{self.joint}: reading stepped {v:+.2f}° beyond what its speed and command explain "
                f"(allowed {lim:.2f}°): encoder zero lost or horn slipped?"
            )
        return f"{self.joint}: follower pinned {v:+.2f}° from its leader while the leader goes on"


def _is_number(v: object) -> bool:
    """``v`` is a real number (a Python or numpy int or float; not a string, complex number or None)."""
    return isinstance(v, Real)


def _is_flag(v: object) -> bool:
    """``v`` is a flag: ``True``/``False`` (Python or numpy) or the integer 0 or 1."""
    return isinstance(v, bool | np.bool_) or (isinstance(v, Integral) and v in (0, 1))


def _per_joint(
    name: str, value: object, names: tuple[str, ...], what: str, ok: Callable[[object], bool]
) -> tuple[Any, ...]:
    """``value`` as one item per joint (a sequence or 1-D array as it is, one value repeated), each ``ok``.

    A string or bytes is refused, not read one value per character; so is an array of two or more dimensions.

    Raises:
        UsageError: A string, a length that is not the number of joints, or an item that is not ``what``.
    """
    n = len(names)
    if isinstance(value, np.ndarray) and value.ndim == 0:
        value = value.item()
    if isinstance(value, str | bytes):
        raise UsageError(f"monitor: {name} is a string ({value!r}); expected {what} or one per joint")
    if isinstance(value, np.ndarray):
        if value.ndim > 1:
            raise UsageError(f"monitor: {name} has shape {value.shape}; expected ({n},), one value per joint")
        value = value.tolist()
    if not isinstance(value, Sequence):
        if not ok(value):
            raise UsageError(f"monitor: {name} is {value!r} ({type(value).__name__}); expected {what} or one per joint")
        return (value,) * n
    if len(value) != n:
        raise UsageError(f"monitor: {name} has {len(value)} values for {n} joints")
    for joint, v in zip(names, value, strict=True):
        if not ok(v):
            raise UsageError(f"monitor: {name} of joint {joint} is {v!r} ({type(v).__name__}); expected {what}")
    return tuple(value)


def _floats(name: str, value: object, names: tuple[str, ...]) -> tuple[float, ...]:
    """``value`` as one float per joint (see :func:`_per_joint`)."""
    return tuple(float(v) for v in _per_joint(name, value, names, "a number", _is_number))


def _number(name: str, value: object) -> float:
    """A single number ``value`` as a float; a string or anything else not a real number refused."""
    if isinstance(value, np.ndarray) and value.ndim == 0:
        value = value.item()
    if not isinstance(value, Real):
        raise UsageError(f"monitor: {name} is {value!r} ({type(value).__name__}); expected a number")
    return float(value)


@dataclass(frozen=True)
class MonitorConfig:
    """What :class:`robocal.core.health.monitor.Monitor` checks, per joint (build it with :func:`monitor_config`).

    Attributes:
        joint_names: Joint names, in the order of the arrays given to ``update``.
        lower_rad: Lower stop of each joint in its calibrated frame, rad.
        upper_rad: Upper stop of each joint, rad.
        max_speed_rad_s: Highest speed each joint can move at, rad/s.
        max_accel_rad_s2: Highest acceleration of each joint's reading (the operator's hand or the servo), rad/s².
        noise_rad: Reading noise and resolution of each joint (a few encoder counts), rad.
        wraps: Per joint: the reading can land on another 2π branch (multi-turn Robstride readings).
        leader_paired: Per joint: a leader reading comes with ``update`` for it (teleoperation).
        margin_rad: How far past a stop a reading may go before it is flagged, rad.
        pin_residual_rad: Leader − follower beyond which a still follower counts as pinned, rad.
        pin_still_rad: How little the follower moves while pinned, rad.
        pin_time_s: How long it must stay pinned before the flag, s.
        step_holdoff_s: After a step flag, how long the joint's further steps are not flagged again (the follower
            moving back to its command after a zero slip), s.
        history: Flags kept in ``Monitor.history`` (the oldest dropped first).
    """

    joint_names: tuple[str, ...]
    lower_rad: tuple[float, ...]
    upper_rad: tuple[float, ...]
    max_speed_rad_s: tuple[float, ...]
    max_accel_rad_s2: tuple[float, ...]
    noise_rad: tuple[float, ...]
    wraps: tuple[bool, ...]
    leader_paired: tuple[bool, ...]
    margin_rad: float = 2.0 * DEG
    pin_residual_rad: float = 5.0 * DEG
    pin_still_rad: float = 0.5 * DEG
    pin_time_s: float = 0.3
    step_holdoff_s: float = 0.5
    history: int = field(default=10_000)

    def __post_init__(self) -> None:
        # built directly too (not only by monitor_config): the same checks of what each field holds, each field
        # then a tuple of floats or bools (a string is never read one value per character)
        if isinstance(self.joint_names, str | bytes):
            raise UsageError(f"monitor: joint_names is a string ({self.joint_names!r}); expected one name per joint")
        names = tuple(str(j) for j in self.joint_names)
        object.__setattr__(self, "joint_names", names)
        n = len(names)
        if n == 0:
            raise UsageError("monitor: no joints")
        if len(set(names)) != n:
            raise UsageError("monitor: a joint name is given twice")
        for name in ("lower_rad", "upper_rad", "max_speed_rad_s", "max_accel_rad_s2", "noise_rad"):
            values = _floats(name, getattr(self, name), names)
            object.__setattr__(self, name, values)
            if not all(math.isfinite(v) for v in values):
                raise UsageError(f"monitor: {name} must be finite numbers")
        for name in ("wraps", "leader_paired"):
            flags = tuple(bool(v) for v in _per_joint(name, getattr(self, name), names, "True/False", _is_flag))
            object.__setattr__(self, name, flags)
        for name in ("margin_rad", "pin_residual_rad", "pin_still_rad", "pin_time_s", "step_holdoff_s"):
            object.__setattr__(self, name, _number(name, getattr(self, name)))
        if not isinstance(self.history, Integral) or isinstance(self.history, bool):
            raise UsageError(f"monitor: history is {self.history!r}; expected a whole number of flags")
        for j, lo, up in zip(self.joint_names, self.lower_rad, self.upper_rad, strict=True):
            if not lo < up:
                raise UsageError(f"monitor: joint {j}: lower stop {lo} rad is not below upper stop {up} rad")
        for name in ("max_speed_rad_s", "max_accel_rad_s2"):
            if any(v <= 0 for v in getattr(self, name)):
                raise UsageError(f"monitor: {name} must be > 0 for every joint")
        if any(v < 0 for v in self.noise_rad):
            raise UsageError("monitor: noise_rad must be >= 0 for every joint")
        for name in ("margin_rad", "pin_residual_rad", "pin_still_rad", "pin_time_s", "step_holdoff_s"):
            v = getattr(self, name)
            if not (math.isfinite(v) and v >= 0):
                raise UsageError(f"monitor: {name} must be a finite number >= 0, got {v!r}")
        if self.history < 1:
            raise UsageError(f"monitor: history must be >= 1, got {self.history}")


def monitor_config(
    joint_names: JointNames,
    lower_rad: JointValues,
    upper_rad: JointValues,
    max_speed_rad_s: JointValues,
    *,
    max_accel_rad_s2: JointValues = 50.0,
    noise_rad: JointValues = 2 * 2 * math.pi / 4096,
    wraps: JointFlags = False,
    leader_paired: JointFlags = False,
    margin_rad: float | np.floating[Any] = 2.0 * DEG,
    pin_residual_rad: float | np.floating[Any] = 5.0 * DEG,
    pin_still_rad: float | np.floating[Any] = 0.5 * DEG,
    pin_time_s: float | np.floating[Any] = 0.3,
    step_holdoff_s: float | np.floating[Any] = 0.5,
) -> MonitorConfig:
    """A :class:`MonitorConfig` from per-joint sequences or numpy arrays, or one value for every joint.

    Args:
        joint_names: Joint names, shape ``(N,)``.
        lower_rad: Lower stops, rad, shape ``(N,)``.
        upper_rad: Upper stops, rad, shape ``(N,)``.
        max_speed_rad_s: Speed limit(s), rad/s.
        max_accel_rad_s2: Acceleration limit(s) of the reading, rad/s² (50 rad/s²: a brisk human hand on a
            leader arm, and a position-controlled follower following it).
        noise_rad: Reading noise(s), rad (default two counts of a 4096-count encoder, 0.18°).
        wraps: Joint(s) whose readings can land on another 2π branch.
        leader_paired: Joint(s) a leader reading comes with.
        margin_rad: Stop margin, rad (2°).
        pin_residual_rad: Pinned-follower threshold, rad (5°, above the 0.6-1.8° sag of a follower at P = 16).
        pin_still_rad: Pinned follower moves less than this, rad.
        pin_time_s: Pinned for at least this long, s.
        step_holdoff_s: Quiet time after a step flag, s.

    Raises:
        UsageError: Lengths that differ, a lower stop not below the upper one, non-finite or negative limits; a
            string (or bytes) for a per-joint value (it is not read one value per character), a value that is not
            a number, a flag that is not True/False.
    """
    if isinstance(joint_names, str | bytes):
        raise UsageError(f"monitor: joint_names is a string ({joint_names!r}); expected one name per joint")
    names = tuple(str(n) for n in joint_names)
    return MonitorConfig(
        names,
        _floats("lower_rad", lower_rad, names),
        _floats("upper_rad", upper_rad, names),
        _floats("max_speed_rad_s", max_speed_rad_s, names),
        _floats("max_accel_rad_s2", max_accel_rad_s2, names),
        _floats("noise_rad", noise_rad, names),
        tuple(bool(v) for v in _per_joint("wraps", wraps, names, "True/False", _is_flag)),
        tuple(bool(v) for v in _per_joint("leader_paired", leader_paired, names, "True/False", _is_flag)),
        margin_rad=_number("margin_rad", margin_rad),
        pin_residual_rad=_number("pin_residual_rad", pin_residual_rad),
        pin_still_rad=_number("pin_still_rad", pin_still_rad),
        pin_time_s=_number("pin_time_s", pin_time_s),
        step_holdoff_s=_number("step_holdoff_s", step_holdoff_s),
    )
