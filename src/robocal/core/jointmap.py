"""The canonical joint map.

Every joint calibration robocal handles is stored in this one form::

    q_joint = direction · scale · (raw − homing_offset)        position
    v_joint = direction · scale · v_raw                        velocity and effort (no offset)
    raw     = direction · q_joint / scale + homing_offset      inverse

``direction`` is ±1 (wiring sign), ``homing_offset`` is in the motor's raw unit (rad for Robstride, ticks for
servos) and ``scale`` converts raw units to joint units (1 for Robstride; 2π/4096 rad per tick for a 4096-tick
servo). Because ``direction`` is ±1, ``direction == 1/direction`` and the inverse is exact up to one rounding
of the scale.
"""

from __future__ import annotations

import math
from collections import Counter
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any, SupportsFloat

import numpy as np
from numpy.typing import ArrayLike

from ..errors import InvalidCalibrationError, JointMismatchError, ShapeMismatchError
from .arrays import FloatArray

__all__ = ["TWO_PI", "FloatArray", "JointMap", "RobotCalibration"]

TWO_PI = math.tau
_SMALLEST_SCALE = float(np.finfo(np.float64).tiny)
"""Smallest accepted scale: the smallest normal double, whose inverse is still finite."""
_F64 = np.dtype(np.float64)
_BLOCK_ELEMENTS = 16384  # 128 KiB of float64 per block: stays in L2 between the two passes


def _check_direction(direction: Any, where: str) -> int:
    text = repr(direction) if len(repr(direction)) <= 40 else f"{repr(direction)[:39]}…"
    try:
        d = float(direction)
    except OverflowError:
        d = math.nan
    except (TypeError, ValueError):
        raise InvalidCalibrationError(f"{where}: direction {text} is not a number; expected -1 or +1") from None
    if isinstance(direction, bool) or d not in (-1.0, 1.0):
        raise InvalidCalibrationError(f"{where}: direction {text} is invalid; expected -1 or +1")
    return int(d)


def _check_finite(value: Any, field: str, where: str) -> float:
    if isinstance(value, bool):
        raise InvalidCalibrationError(f"{where}: {field} {value!r} is a boolean; expected a number")
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise InvalidCalibrationError(f"{where}: {field} {value!r} is not a number") from None
    if not math.isfinite(v):
        raise InvalidCalibrationError(f"{where}: {field} is {v}; expected a finite number")
    return v


@dataclass(frozen=True, slots=True)
class JointMap:
    """Calibration of one joint: ``q = direction · scale · (raw − homing_offset)``.

    Attributes:
        direction: Wiring sign, −1 or +1.
        homing_offset: Raw reading (motor frame, raw units) at which the joint is at zero.
        scale: Joint units per raw unit (> 0). 1.0 when raw is already in rad.
    """

    direction: int = 1
    homing_offset: float = 0.0
    scale: float = 1.0

    def __post_init__(self) -> None:
        object.__setattr__(self, "direction", _check_direction(self.direction, "joint map"))
        object.__setattr__(
            self, "homing_offset", _check_finite(self.homing_offset, "homing_offset", "joint map")
        )
        scale = _check_finite(self.scale, "scale", "joint map")
        if scale <= 0.0:
            raise InvalidCalibrationError(f"joint map: scale {scale} must be > 0")
        object.__setattr__(self, "scale", scale)

    def to_joint(self, raw: ArrayLike) -> Any:
        """Map raw position(s) to joint position(s): ``direction·scale·(raw − homing_offset)``."""
        return self.direction * self.scale * (np.asarray(raw, dtype=np.float64) - self.homing_offset)

    def to_raw(self, q: ArrayLike) -> Any:
        """Map joint position(s) to raw position(s): ``direction·q/scale + homing_offset``."""
        return self.direction * np.asarray(q, dtype=np.float64) / self.scale + self.homing_offset


def _vector(values: ArrayLike, n: int, field: str) -> FloatArray:
    raw = np.asarray(values)
    if raw.dtype == np.bool_:
        raise InvalidCalibrationError(f"{field} holds booleans; expected numbers")
    arr = np.array(raw, dtype=np.float64)
    if arr.ndim == 0:
        arr = np.full(n, float(arr))
    if arr.shape != (n,):
        raise ShapeMismatchError(f"{field} has shape {arr.shape}; expected ({n},) for {n} joints")
    arr.flags.writeable = False
    return arr


@dataclass(frozen=True, eq=False)
class RobotCalibration:
    """Calibration of a whole robot: joint names in order plus per-joint arrays.

    One numpy expression maps a whole robot per tick (shape ``(N,)``) or a whole recording (shape ``(T, N)``);
    the last axis is always the joint axis, in ``joint_names`` order.

    Attributes:
        joint_names: Joint names, unique, in array order.
        direction: Shape ``(N,)``, each −1.0 or +1.0.
        homing_offset: Shape ``(N,)``, raw units (motor frame).
        scale: Shape ``(N,)``, joint units per raw unit, > 0.
    """

    joint_names: tuple[str, ...]
    direction: FloatArray
    homing_offset: FloatArray
    scale: FloatArray
    _gain: FloatArray = field(init=False, repr=False, compare=False)
    _inv_gain: FloatArray = field(init=False, repr=False, compare=False)
    _index: dict[str, int] = field(init=False, repr=False, compare=False)
    _state_offset: FloatArray = field(init=False, repr=False, compare=False)
    _state_gain: FloatArray = field(init=False, repr=False, compare=False)
    _state_inv_gain: FloatArray = field(init=False, repr=False, compare=False)
    _state_inv_offset: FloatArray = field(init=False, repr=False, compare=False)

    def __init__(
        self,
        joint_names: Sequence[str],
        direction: ArrayLike,
        homing_offset: ArrayLike,
        scale: ArrayLike = 1.0,
    ) -> None:
        if isinstance(joint_names, str):
            raise InvalidCalibrationError(
                f"joint_names {joint_names!r} is one string; expected a sequence of joint names"
            )
        names = tuple(joint_names)
        for name in names:
            if not isinstance(name, str) or not name:
                raise InvalidCalibrationError(f"joint name {name!r} is not a non-empty string")
        index = {name: i for i, name in enumerate(names)}
        if len(index) != len(names):
            dupes = sorted(n for n, count in Counter(names).items() if count > 1)
            raise JointMismatchError(f"duplicate joint names: {', '.join(dupes)}")
        n = len(names)
        try:
            d = _vector(direction, n, "direction")
            h = _vector(homing_offset, n, "homing_offset")
            s = _vector(scale, n, "scale")
        except (TypeError, ValueError) as exc:
            if isinstance(exc, InvalidCalibrationError):
                raise
            raise InvalidCalibrationError(f"calibration arrays are not numeric: {exc}") from None
        # vectorised checks; the first offending joint (in order, direction before offset before scale) is named
        # a subnormal scale (< 2.2e-308) would give an infinite inverse gain
        bad = ~((d == 1.0) | (d == -1.0)) | ~np.isfinite(h) | ~(np.isfinite(s) & (s >= _SMALLEST_SCALE))
        if bad.any():
            i = int(np.flatnonzero(bad)[0])
            name = names[i]
            if d[i] not in (-1.0, 1.0):
                raise InvalidCalibrationError(
                    f"joint {name!r}: direction {d[i]:g} is invalid; expected -1 or +1"
                )
            if not math.isfinite(h[i]):
                raise InvalidCalibrationError(
                    f"joint {name!r}: homing_offset is {h[i]}; expected a finite number"
                )
            raise InvalidCalibrationError(
                f"joint {name!r}: scale {s[i]} must be finite and > 0 (at least {_SMALLEST_SCALE:g})"
            )
        object.__setattr__(self, "joint_names", names)
        object.__setattr__(self, "direction", d)
        object.__setattr__(self, "homing_offset", h)
        object.__setattr__(self, "scale", s)
        gain = d * s
        gain.flags.writeable = False
        inv_gain = d / s
        inv_gain.flags.writeable = False
        object.__setattr__(self, "_gain", gain)
        object.__setattr__(self, "_inv_gain", inv_gain)
        object.__setattr__(self, "_index", index)  # a dict: RobotCalibration must stay picklable
        # (3, N) offsets of the fused state map: x − (+0.0) and x + (−0.0) leave every x (and its zero sign)
        # unchanged, so velocity and effort rows stay bit-identical to gain·x and x/gain
        state_offset = np.zeros((3, n))
        state_offset[0] = h
        state_inv_offset = np.full((3, n), -0.0)
        state_inv_offset[0] = h
        state_gain = np.tile(gain, (3, 1))
        state_inv_gain = np.tile(inv_gain, (3, 1))
        for a in (state_offset, state_inv_offset, state_gain, state_inv_gain):
            a.flags.writeable = False
        object.__setattr__(self, "_state_gain", state_gain)
        object.__setattr__(self, "_state_inv_gain", state_inv_gain)
        object.__setattr__(self, "_state_offset", state_offset)
        object.__setattr__(self, "_state_inv_offset", state_inv_offset)

    # ----------------------------------------------------------------------------------------- constructors
    @classmethod
    def identity(cls, joint_names: Sequence[str], direction: ArrayLike = 1.0) -> RobotCalibration:
        """Calibration with zero offsets and unit scale (optionally with directions): ``q = direction·raw``."""
        return cls(joint_names, direction, 0.0, 1.0)

    @classmethod
    def from_joint_maps(cls, maps: Mapping[str, JointMap]) -> RobotCalibration:
        """Build from ``{name: JointMap}`` in the mapping's order."""
        names = list(maps)
        return cls(
            names,
            [maps[n].direction for n in names],
            [maps[n].homing_offset for n in names],
            [maps[n].scale for n in names],
        )

    # ---------------------------------------------------------------------------------------------- access
    @property
    def n_joints(self) -> int:
        """Number of joints N."""
        return len(self.joint_names)

    def __len__(self) -> int:
        return len(self.joint_names)

    def __contains__(self, name: object) -> bool:
        try:
            return name in self._index
        except TypeError:  # unhashable
            return False

    def index(self, name: str) -> int:
        """Position of joint ``name`` (O(1)); :class:`JointMismatchError` naming the valid joints if unknown."""
        try:
            return self._index[name]
        except (KeyError, TypeError):
            raise JointMismatchError(
                f"unknown joint {name!r}; known joints: {', '.join(self.joint_names) or '(none)'}"
            ) from None

    def joint_map(self, name: str) -> JointMap:
        """The :class:`JointMap` of one joint."""
        i = self.index(name)
        return JointMap(int(self.direction[i]), float(self.homing_offset[i]), float(self.scale[i]))

    def joint_maps(self) -> dict[str, JointMap]:
        """All joints as ``{name: JointMap}`` in order."""
        return {n: self.joint_map(n) for n in self.joint_names}

    def select(self, joint_names: Iterable[str]) -> RobotCalibration:
        """Reorder or subset the joints. Unknown names raise :class:`JointMismatchError` listing them."""
        names = list(joint_names)
        index = self._index
        missing = [n for n in names if n not in index]
        if missing:
            raise JointMismatchError(
                f"joints not in the calibration: {', '.join(missing)}; known: {', '.join(self.joint_names)}"
            )
        idx = [index[n] for n in names]
        return RobotCalibration(names, self.direction[idx], self.homing_offset[idx], self.scale[idx])

    def with_offsets(self, offsets: Mapping[str, SupportsFloat]) -> RobotCalibration:
        """Copy with the homing offsets of some joints replaced (raw units)."""
        h = self.homing_offset.copy()
        for name, value in offsets.items():
            h[self.index(name)] = _check_finite(value, "homing_offset", f"joint {name!r}")
        return RobotCalibration(self.joint_names, self.direction, h, self.scale)

    def with_directions(self, directions: Mapping[str, int]) -> RobotCalibration:
        """Copy with the directions of some joints replaced."""
        d = self.direction.copy()
        for name, value in directions.items():
            d[self.index(name)] = _check_direction(value, f"joint {name!r}")
        return RobotCalibration(self.joint_names, d, self.homing_offset, self.scale)

    def is_close(self, other: RobotCalibration, atol: float = 1e-12) -> bool:
        """Same joints in the same order, same directions, offsets and scales within ``atol``."""
        return (
            self.joint_names == other.joint_names
            and bool(np.array_equal(self.direction, other.direction))
            and bool(np.allclose(self.homing_offset, other.homing_offset, rtol=0.0, atol=atol))
            and bool(np.allclose(self.scale, other.scale, rtol=0.0, atol=atol))
        )

    def __repr__(self) -> str:
        rows = ", ".join(
            f"{n}: d={int(d):+d} h={h:.6g} s={s:.6g}"
            for n, d, h, s in zip(
                self.joint_names, self.direction, self.homing_offset, self.scale, strict=True
            )
        )
        return f"RobotCalibration({rows})"

    # --------------------------------------------------------------------------------------------- mapping
    def _check(self, x: ArrayLike, what: str) -> FloatArray:
        if type(x) is np.ndarray and x.dtype is _F64 and x.ndim and x.shape[-1] == len(self.joint_names):
            return x  # the per-tick fast path: already a float64 array over the joint axis
        try:
            arr = np.asarray(x, dtype=np.float64)
        except (TypeError, ValueError) as exc:  # ragged nesting, strings, objects
            raise ShapeMismatchError(
                f"{what} is not a numeric array of shape (..., {self.n_joints}): {exc}"
            ) from None
        if arr.ndim == 0:
            if self.n_joints != 1:
                raise ShapeMismatchError(f"{what} is a scalar; expected shape (..., {self.n_joints})")
            return arr
        if arr.shape[-1] != self.n_joints:
            raise ShapeMismatchError(
                f"{what} has shape {arr.shape}; the last axis must have {self.n_joints} joints "
                f"({', '.join(self.joint_names)})"
            )
        return arr

    def to_joint(self, raw: ArrayLike, out: FloatArray | None = None) -> FloatArray:
        """Raw motor positions → joint positions.

        Args:
            raw: Shape ``(N,)``, ``(T, N)`` or ``(..., N)`` in raw units (a scalar when N = 1).
            out: Optional float64 array of the same shape to write into (no allocation); large recordings
                are then processed in cache-sized blocks, close to the speed of a plain copy.

        Returns:
            Joint positions, same shape, joint units (rad).
        """
        r = self._check(raw, "raw position")
        if out is None:
            if r.ndim < 2 or r.size < 4 * _BLOCK_ELEMENTS:
                res: FloatArray = self._gain * (r - self.homing_offset)
                return res.reshape(r.shape)
            out = np.empty(r.shape, dtype=np.float64)
        if not isinstance(out, np.ndarray):
            raise ShapeMismatchError(
                f"out is a {type(out).__name__}; expected a {r.shape} float64 numpy array"
            )
        if out.shape != r.shape or out.dtype != np.float64:
            raise ShapeMismatchError(
                f"out has shape {out.shape} and dtype {out.dtype}; expected {r.shape} float64"
            )
        if r.ndim == 0 or r.size == 0 or not (r.flags.c_contiguous and out.flags.c_contiguous):
            np.multiply(self._gain, r - self.homing_offset, out=out)
            return out
        # Contiguous recording: work on flat blocks against tiled per-joint constants, so every ufunc runs one
        # long contiguous inner loop and the second pass hits the cache.
        n = self.n_joints
        rows = max(1, _BLOCK_ELEMENTS // n)
        step = rows * n
        tiled_h = np.tile(self.homing_offset, rows)
        tiled_g = np.tile(self._gain, rows)
        flat_in = r.reshape(-1)
        flat_out = out.reshape(-1)
        for start in range(0, flat_in.size, step):
            stop = min(start + step, flat_in.size)
            k = stop - start
            o = flat_out[start:stop]
            np.subtract(flat_in[start:stop], tiled_h[:k], out=o)
            np.multiply(o, tiled_g[:k], out=o)
        return out

    def to_raw(self, q: ArrayLike) -> FloatArray:
        """Joint positions → raw motor positions (inverse of :meth:`to_joint`), shape ``(..., N)``."""
        qq = self._check(q, "joint position")
        out: FloatArray = self._inv_gain * qq + self.homing_offset
        return out.reshape(qq.shape)

    def _scaled(self, gain: FloatArray, x: ArrayLike, what: str) -> FloatArray:
        """``gain·x`` over the joint axis (velocity and effort carry no offset)."""
        arr = self._check(x, what)
        out: FloatArray = gain * arr
        return out.reshape(arr.shape)

    def velocity_to_joint(self, v_raw: ArrayLike) -> FloatArray:
        """Raw velocities → joint velocities: ``direction·scale·v`` (no offset), shape ``(..., N)``."""
        return self._scaled(self._gain, v_raw, "raw velocity")

    def velocity_to_raw(self, v_joint: ArrayLike) -> FloatArray:
        """Joint velocities → raw velocities: ``direction·v/scale``, shape ``(..., N)``."""
        return self._scaled(self._inv_gain, v_joint, "joint velocity")

    def effort_to_joint(self, e_raw: ArrayLike) -> FloatArray:
        """Raw efforts → joint efforts: ``direction·scale·e`` (no offset), shape ``(..., N)``."""
        return self._scaled(self._gain, e_raw, "raw effort")

    def effort_to_raw(self, e_joint: ArrayLike) -> FloatArray:
        """Joint efforts → raw efforts: ``direction·e/scale``, shape ``(..., N)``."""
        return self._scaled(self._inv_gain, e_joint, "joint effort")

    def state_to_joint(self, raw_state: ArrayLike, out: FloatArray | None = None) -> FloatArray:
        """Raw position, velocity and effort → joint frame in one fused affine map (the per-tick hot path).

        Row 0 is ``direction·scale·(raw − homing_offset)``, rows 1 and 2 are ``direction·scale·x``: the
        same numbers, bit for bit, as :meth:`to_joint`, :meth:`velocity_to_joint` and
        :meth:`effort_to_joint`, in two vectorised operations instead of six.

        Args:
            raw_state: Shape ``(3, N)`` or ``(..., 3, N)``: rows position, velocity, effort, raw units.
            out: Optional float64 array of the same shape to write into (may be ``raw_state`` itself).

        Returns:
            Joint-frame state, same shape: rows position (rad), velocity (rad/s), effort (N·m).
        """
        x = self._check_state(raw_state, "raw state")
        if out is None:
            res: FloatArray = x - self._state_offset
        else:
            res = np.subtract(x, self._state_offset, out=self._check_out(out, x.shape))
        res *= self._state_gain  # (3, N) like x: a same-shape multiply, much cheaper than a broadcast
        return res

    def state_to_raw(self, joint_state: ArrayLike, out: FloatArray | None = None) -> FloatArray:
        """Joint-frame position, velocity and effort → raw (inverse of :meth:`state_to_joint`).

        Bit for bit the same as :meth:`to_raw`, :meth:`velocity_to_raw` and :meth:`effort_to_raw`.

        Args:
            joint_state: Shape ``(3, N)`` or ``(..., 3, N)``: rows position, velocity, effort, joint units.
            out: Optional float64 array of the same shape to write into.

        Returns:
            Raw state, same shape.
        """
        x = self._check_state(joint_state, "joint state")
        if out is None:
            res: FloatArray = x * self._state_inv_gain
        else:
            res = np.multiply(x, self._state_inv_gain, out=self._check_out(out, x.shape))
        res += self._state_inv_offset
        return res

    def _check_state(self, x: ArrayLike, what: str) -> FloatArray:
        n = len(self.joint_names)
        if type(x) is np.ndarray and x.dtype is _F64 and x.shape[-2:] == (3, n):
            return x
        arr = self._check(x, what)
        if arr.ndim < 2 or arr.shape[-2] != 3:
            raise ShapeMismatchError(
                f"{what} has shape {arr.shape}; expected (3, {n}) rows position, velocity, effort"
            )
        return arr

    @staticmethod
    def _check_out(out: Any, shape: tuple[int, ...]) -> FloatArray:
        if not isinstance(out, np.ndarray) or out.shape != shape or out.dtype != np.float64:
            got = (
                f"shape {out.shape} and dtype {out.dtype}"
                if isinstance(out, np.ndarray)
                else type(out).__name__
            )
            raise ShapeMismatchError(f"out has {got}; expected a {shape} float64 numpy array")
        return out

    def unwrap_to_limits(
        self,
        raw: ArrayLike,
        lower: ArrayLike,
        upper: ArrayLike,
        period_raw: ArrayLike = TWO_PI,
    ) -> FloatArray:
        """Choose, per joint, the raw branch ``raw + k·period`` that puts the joint inside its limits.

        After a power cycle an absolute single-turn encoder reports its position modulo one turn. When the
        turn's wrap point lies inside a joint's travel, the reading can be off by one period. This picks the
        integer ``k`` whose joint position lies inside ``[lower, upper]``, or, when none does, the one closest
        to the middle of the range (the moteus "set output nearest" rule).

        Args:
            raw: Raw positions, shape ``(N,)`` (first reading after power-on), raw units.
            lower: Lower joint limits, shape ``(N,)`` or scalar, joint units.
            upper: Upper joint limits, shape ``(N,)`` or scalar, joint units.
            period_raw: Encoder period in raw units (2π for Robstride, 4096 for a 4096-tick servo).

        Returns:
            Raw positions, shape ``(N,)``, shifted by whole periods.
        """
        r = self._check(raw, "raw position")
        lo = np.broadcast_to(np.asarray(lower, dtype=np.float64), r.shape)
        up = np.broadcast_to(np.asarray(upper, dtype=np.float64), r.shape)
        period = np.broadcast_to(np.asarray(period_raw, dtype=np.float64), r.shape)
        if not (np.all(np.isfinite(r)) and np.all(np.isfinite(lo)) and np.all(np.isfinite(up))):
            raise InvalidCalibrationError("unwrap_to_limits: raw positions and limits must be finite")
        if not np.all(np.isfinite(period) & (period > 0)):
            raise InvalidCalibrationError("unwrap_to_limits: the encoder period must be finite and > 0")
        inverted = np.broadcast_to(lo > up, r.shape).reshape(-1, self.n_joints).any(axis=0)
        bad = np.flatnonzero(inverted)
        if bad.size:
            names = ", ".join(self.joint_names[i] for i in bad)
            raise InvalidCalibrationError(f"unwrap_to_limits: lower limit above upper limit for {names}")
        mid_joint = 0.5 * (lo + up)
        mid_raw = self._inv_gain * mid_joint + self.homing_offset
        k = np.round((mid_raw - r) / period)
        out: FloatArray = r + k * period
        return out
