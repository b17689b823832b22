"""LeRobot's 2024 legacy calibration scheme (until 2025-06), pure numpy.

Six parallel arrays per arm (:class:`LegacyCalibration`); DEGREE motors read
``deg = ((−raw if drive_mode else raw) + homing_offset) / 2048 · 180``, LINEAR motors a percentage of
``start_pos..end_pos``; LeRobot raises outside :data:`LEGACY_BOUNDS`.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
import numpy.typing as npt

from ...errors import InvalidCalibrationError, JointOutOfRangeError, ShapeMismatchError
from ..arrays import FloatArray, IntArray
from ..conventions import homing_from_lerobot_legacy
from ..jointmap import RobotCalibration
from ..vendors import expected_homing_vendors, homing_vendor
from ._values import _as_float_array, _check_resolution, _check_values, _to_ticks

__all__ = [
    "HALF_TURN_DEGREE",
    "LEGACY_BOUNDS",
    "LOWER_BOUND_DEGREE",
    "LOWER_BOUND_LINEAR",
    "UPPER_BOUND_DEGREE",
    "UPPER_BOUND_LINEAR",
    "LegacyCalibration",
    "apply_calibration",
    "apply_legacy",
    "autocorrect_legacy",
    "avoid_rotation_reset",
    "degree_joint_map",
    "degrees_to_steps",
    "legacy_calibration_from_poses",
    "nearest_rounded_position",
    "revert_calibration",
    "revert_legacy",
    "to_robot_calibration",
]


HALF_TURN_DEGREE = 180.0
LOWER_BOUND_DEGREE = -270.0
UPPER_BOUND_DEGREE = 270.0
LOWER_BOUND_LINEAR = -10.0
UPPER_BOUND_LINEAR = 110.0
LEGACY_BOUNDS: dict[str, tuple[float, float]] = {
    "DEGREE": (LOWER_BOUND_DEGREE, UPPER_BOUND_DEGREE),
    "LINEAR": (LOWER_BOUND_LINEAR, UPPER_BOUND_LINEAR),
}
"""Where LeRobot's legacy ``apply_calibration`` raises, per calibration mode (the same for every arm)."""


@dataclass(frozen=True, eq=False)
class LegacyCalibration:
    """LeRobot legacy calibration (2024 → 2025-06): six parallel arrays indexed like ``motor_names``.

    Attributes:
        motor_names: Motor names in array order.
        homing_offset: Shape ``(n,)``, ticks added to the drive-mode-applied raw ticks.
        drive_mode: Shape ``(n,)``, 1 = negate raw.
        start_pos: Shape ``(n,)``, raw ticks at the zero pose (LINEAR 0 %).
        end_pos: Shape ``(n,)``, raw ticks at the rotated pose, negated where drive_mode = 1 (LINEAR 100 %).
        calib_mode: ``"DEGREE"`` or ``"LINEAR"`` per motor.
    """

    motor_names: tuple[str, ...]
    homing_offset: IntArray
    drive_mode: IntArray
    start_pos: IntArray
    end_pos: IntArray
    calib_mode: tuple[str, ...]

    def __init__(
        self,
        motor_names: Sequence[str],
        homing_offset: npt.ArrayLike,
        drive_mode: npt.ArrayLike,
        start_pos: npt.ArrayLike,
        end_pos: npt.ArrayLike,
        calib_mode: Sequence[str],
    ) -> None:
        names = tuple(motor_names)
        n = len(names)
        if len(set(names)) != n:
            raise InvalidCalibrationError(f"legacy calibration: duplicate motor names in {list(names)}")
        arrays: dict[str, IntArray] = {}
        for field, val in (
            ("homing_offset", homing_offset),
            ("drive_mode", drive_mode),
            ("start_pos", start_pos),
            ("end_pos", end_pos),
        ):
            try:
                arr = np.asarray(val)
                if arr.shape != (n,):
                    raise ShapeMismatchError(
                        f"legacy calibration: {field} has shape {arr.shape}; expected ({n},)"
                    )
                arrays[field] = arr.astype(np.int64)
            except (OverflowError, TypeError, ValueError) as exc:
                if isinstance(exc, ShapeMismatchError):
                    raise
                raise InvalidCalibrationError(
                    f"legacy calibration: {field} {list(val) if isinstance(val, Sequence) else val!r} is not "
                    f"a list of 64-bit integers ({exc})"
                ) from None
            arrays[field].flags.writeable = False
        if not np.all(np.isin(arrays["drive_mode"], (0, 1))):
            raise InvalidCalibrationError(
                f"legacy calibration: drive_mode {arrays['drive_mode'].tolist()}; expected 0/1"
            )
        modes = tuple(calib_mode)
        if len(modes) != n or any(m not in ("DEGREE", "LINEAR") for m in modes):
            raise InvalidCalibrationError(
                f"legacy calibration: calib_mode {list(modes)}; expected {n} entries of 'DEGREE' or 'LINEAR'"
            )
        object.__setattr__(self, "motor_names", names)
        for field, arr in arrays.items():
            object.__setattr__(self, field, arr)
        object.__setattr__(self, "calib_mode", modes)

    def __eq__(self, other: object) -> bool:
        if not isinstance(other, LegacyCalibration):
            return NotImplemented
        return (
            self.motor_names == other.motor_names
            and self.calib_mode == other.calib_mode
            and all(
                np.array_equal(getattr(self, f), getattr(other, f))
                for f in ("homing_offset", "drive_mode", "start_pos", "end_pos")
            )
        )

    __hash__ = None  # type: ignore[assignment]

    def with_homing_offset(self, homing_offset: npt.ArrayLike) -> LegacyCalibration:
        """Copy with a new ``homing_offset`` array."""
        return LegacyCalibration(
            self.motor_names, homing_offset, self.drive_mode, self.start_pos, self.end_pos, self.calib_mode
        )


def _legacy_message(name: str, value: float, linear: bool) -> str:
    if linear:
        return (
            f"Wrong motor position range detected for {name}. "
            f"Expected to be in nominal range of [0, 100] % (a full linear translation), "
            f"with a maximum range of [{LOWER_BOUND_LINEAR:g}, {UPPER_BOUND_LINEAR:g}] % to account for some "
            f"imprecision during calibration, but present value is {value} %. "
            "This might be due to a cable connection issue creating an artificial jump in motor values. "
            "You need to recalibrate by running: `python lerobot/scripts/control_robot.py calibrate`"
        )
    return (
        f"Wrong motor position range detected for {name}. "
        f"Expected to be in nominal range of [-{HALF_TURN_DEGREE:g}, {HALF_TURN_DEGREE:g}] degrees "
        "(a full rotation), "
        f"with a maximum range of [{LOWER_BOUND_DEGREE:g}, {UPPER_BOUND_DEGREE:g}] degrees to account for "
        f"joints that can rotate a bit more, but present value is {value} degree. "
        "This might be due to a cable connection issue creating an artificial 360 degrees jump in motor "
        "values. "
        "You need to recalibrate by running: `python lerobot/scripts/control_robot.py calibrate`"
    )


def _legacy_unchecked(raw: FloatArray, cal: LegacyCalibration, resolution: int) -> FloatArray:
    half = resolution // 2
    linear = np.array([m == "LINEAR" for m in cal.calib_mode])
    v = np.where(cal.drive_mode.astype(bool), -raw, raw)
    deg = (v + cal.homing_offset) / half * HALF_TURN_DEGREE
    span = (cal.end_pos - cal.start_pos).astype(np.float64)
    with np.errstate(divide="ignore", invalid="ignore"):
        pct = (raw - cal.start_pos) / span * 100
    out: FloatArray = np.where(linear, pct, deg)
    return out


def apply_legacy(raw_ticks: npt.ArrayLike, cal: LegacyCalibration, *, resolution: int = 4096) -> FloatArray:
    """Legacy ``apply_calibration``: raw ticks → DEGREE degrees / LINEAR percent.

    DEGREE: ``deg = ((−raw if drive_mode else raw) + homing_offset) / 2048 · 180``, error outside ±270
    (±270 itself passes). LINEAR: ``pct = (raw − start_pos)/(end_pos − start_pos)·100`` (drive mode not
    applied), error outside −10..110 (and for ``start_pos == end_pos``, huggingface/lerobot#607).

    Args:
        raw_ticks: Shape ``(..., n)`` int32-cast raw ticks.
        cal: The legacy calibration.
        resolution: Ticks per turn.

    Returns:
        Shape ``(..., n)`` float64.

    Raises:
        JointOutOfRangeError: With LeRobot's message naming the first offending motor.
    """
    n = len(cal.motor_names)
    raw = _check_values(raw_ticks, n, "raw")
    out = _legacy_unchecked(raw, cal, resolution)
    linear = np.array([m == "LINEAR" for m in cal.calib_mode])
    lo = np.where(linear, LOWER_BOUND_LINEAR, LOWER_BOUND_DEGREE)
    hi = np.where(linear, UPPER_BOUND_LINEAR, UPPER_BOUND_DEGREE)
    bad = ~((out >= lo) & (out <= hi))  # NaN counts as bad
    if np.any(bad):
        idx = np.argwhere(bad)[0]
        j = int(idx[-1])
        raise JointOutOfRangeError(
            _legacy_message(cal.motor_names[j], float(out[tuple(idx)]), bool(linear[j]))
        )
    return out


def revert_legacy(values: npt.ArrayLike, cal: LegacyCalibration, *, resolution: int = 4096) -> IntArray:
    """Legacy ``revert_calibration``: degrees / percent → raw ticks, ``np.round`` (half to even).

    DEGREE: ``steps = deg/180·2048 − homing_offset``, negated if drive_mode. LINEAR:
    ``raw = pct/100·(end_pos − start_pos) + start_pos``.

    Returns:
        Shape ``(..., n)`` int64 ticks.
    """
    n = len(cal.motor_names)
    v = _check_values(values, n, "values")
    half = resolution // 2
    linear = np.array([m == "LINEAR" for m in cal.calib_mode])
    steps = v / HALF_TURN_DEGREE * half - cal.homing_offset
    steps = np.where(cal.drive_mode.astype(bool), -steps, steps)
    lin = v / 100 * (cal.end_pos - cal.start_pos) + cal.start_pos
    return _to_ticks(np.round(np.where(linear, lin, steps)), "values")


def autocorrect_legacy(
    raw_ticks: npt.ArrayLike, cal: LegacyCalibration, *, resolution: int = 4096
) -> tuple[FloatArray, LegacyCalibration]:
    """Legacy ``apply_calibration_autocorrect``: shift out-of-range motors' offsets by whole turns.

    Only motors whose value is out of range are corrected: ``factor = ceil(low)`` with DEGREE
    ``low = (−half − v − h)/res``, ``upp = (half − v − h)/res`` (``v`` drive-mode applied); LINEAR
    ``low = (start − raw)/res``, ``upp = (end − raw)/res``; ``homing_offset += factor·res``.

    Args:
        raw_ticks: Shape ``(n,)`` one reading.
        cal: The legacy calibration (not modified).
        resolution: Ticks per turn.

    Returns:
        ``(values, corrected calibration)``.

    Raises:
        JointOutOfRangeError: No whole-turn correction brings a motor inside its bounds.
    """
    n = len(cal.motor_names)
    raw = _check_values(raw_ticks, n, "raw")
    if raw.ndim != 1:
        raise ShapeMismatchError(f"autocorrect takes one reading of shape ({n},); got {raw.shape}")
    out = _legacy_unchecked(raw, cal, resolution)
    homing = cal.homing_offset.copy()
    half = resolution // 2
    for j, name in enumerate(cal.motor_names):
        linear = cal.calib_mode[j] == "LINEAR"
        lo, hi = (
            (LOWER_BOUND_LINEAR, UPPER_BOUND_LINEAR) if linear else (LOWER_BOUND_DEGREE, UPPER_BOUND_DEGREE)
        )
        if lo <= out[j] <= hi:
            continue
        if linear:
            low = (cal.start_pos[j] - raw[j]) / resolution
            upp = (cal.end_pos[j] - raw[j]) / resolution
        else:
            v = -raw[j] if cal.drive_mode[j] else raw[j]
            low = (-half - v - homing[j]) / resolution
            upp = (half - v - homing[j]) / resolution
        factor = math.ceil(low)
        if factor > upp:
            raise JointOutOfRangeError(f"No integer found between bounds [{low=}, {upp=}] for motor {name}")
        homing[j] += factor * resolution
    new_cal = cal.with_homing_offset(homing)
    return apply_legacy(raw, new_cal, resolution=resolution), new_cal


def avoid_rotation_reset(raw_ticks: npt.ArrayLike, resolution: int = 4096) -> IntArray:
    """Legacy Feetech ``avoid_rotation_reset`` over a time series, reproduced with its flaw.

    Per motor: if ``|prev − raw| > half`` use ``raw − res`` when ``prev < raw`` else ``raw + res``, where
    ``prev`` is the previous *output*. Only ±res is ever added, so a second wrap is mis-unwrapped.

    Args:
        raw_ticks: Shape ``(T, n)`` or ``(T,)`` readings in time order.
        resolution: Ticks per turn.

    Returns:
        Same shape, int64.
    """
    arr = np.asarray(raw_ticks, dtype=np.int64)
    flat = arr.reshape(arr.shape[0], -1)
    out = flat.copy()
    half = resolution // 2
    for t in range(1, flat.shape[0]):
        prev = out[t - 1]
        raw = flat[t]
        jump = np.abs(prev - raw) > half
        out[t] = np.where(jump, np.where(prev < raw, raw - resolution, raw + resolution), raw)
    result: IntArray = out.reshape(arr.shape)
    return result


def degrees_to_steps(degrees: npt.ArrayLike, resolution: int = 4096) -> IntArray:
    """Legacy ``convert_degrees_to_steps``: ``deg / 180 · res / 2`` truncated toward zero (``astype(int)``).

    90 → 1024, 45.5 → 517, −45.5 → −517.
    """
    resolution = _check_resolution(resolution)
    d = _as_float_array(degrees, "degrees")
    if not np.all(np.isfinite(d)):
        raise InvalidCalibrationError("degrees contains NaN or inf; expected finite numbers")
    return _to_ticks(np.trunc(d / HALF_TURN_DEGREE * resolution / 2), "degrees")


def nearest_rounded_position(ticks: npt.ArrayLike, resolution: int = 4096) -> IntArray:
    """Dynamixel legacy ``compute_nearest_rounded_position``: nearest quarter turn (half to even)."""
    quarter = resolution // 4
    out: IntArray = (np.round(np.asarray(ticks, dtype=np.float64) / quarter) * quarter).astype(np.int64)
    return out


def legacy_calibration_from_poses(
    motor_names: Sequence[str],
    zero_pos: npt.ArrayLike,
    rotated_pos: npt.ArrayLike,
    *,
    vendor: str,
    calib_mode: Sequence[str] | None = None,
    resolution: int = 4096,
) -> LegacyCalibration:
    """Legacy zero + rotated (+90°) pose calibration (legacy ``run_arm_calibration``).

    ``drive_mode = rotated < zero``; the rotated pose is negated where inverted (this negated value is stored
    as ``end_pos``); Dynamixel rounds it to the nearest quarter turn (half to even), Feetech uses it exactly;
    ``homing_offset = quarter − value``.

    Args:
        motor_names: Motor names.
        zero_pos: Shape ``(n,)`` raw ticks at the zero pose.
        rotated_pos: Shape ``(n,)`` raw ticks at the rotated pose.
        vendor: ``"dynamixel"`` (rounding) or ``"feetech"`` (exact).
        calib_mode: Per motor; default all DEGREE (Feetech: ``gripper`` LINEAR).
        resolution: Ticks per turn.

    Returns:
        The legacy calibration.
    """
    n = len(motor_names)
    zero = np.asarray(zero_pos, dtype=np.int64)
    rot = np.asarray(rotated_pos, dtype=np.int64)
    if zero.shape != (n,) or rot.shape != (n,):
        raise ShapeMismatchError(f"poses have shapes {zero.shape} and {rot.shape}; expected ({n},)")
    drive_mode = (rot < zero).astype(np.int64)
    rot_driven = np.where(drive_mode == 1, -rot, rot)
    quarter = resolution // 4
    spec = homing_vendor(vendor)
    if spec is None:
        raise InvalidCalibrationError(f"vendor {vendor!r}: expected {expected_homing_vendors()}")
    nearest = nearest_rounded_position(rot_driven, resolution) if spec.legacy_quarter_turn else rot_driven
    homing = quarter - nearest
    if calib_mode is None:
        modes = ["LINEAR" if (spec.legacy_linear_gripper and m == "gripper") else "DEGREE" for m in motor_names]
    else:
        modes = list(calib_mode)
    return LegacyCalibration(motor_names, homing, drive_mode, zero, rot_driven, modes)


# ------------------------------------------------------------- LeRobot's names, one motor as a scalar
def _one_motor(
    kernel: Callable[[npt.ArrayLike, LegacyCalibration], npt.NDArray[Any]],
    x: npt.ArrayLike,
    cal: LegacyCalibration,
) -> npt.NDArray[Any]:
    """A scalar for a one-motor calibration is that motor's value (result of shape ``()``)."""
    if not isinstance(cal, LegacyCalibration):
        raise InvalidCalibrationError(
            f"cal is a {type(cal).__name__}; expected a LegacyCalibration (see read_legacy)"
        )
    if len(cal.motor_names) == 1 and np.ndim(x) == 0:
        one: npt.NDArray[Any] = kernel(np.asarray(x)[np.newaxis], cal)[..., 0]
        return one
    return kernel(x, cal)


def apply_calibration(raw: npt.ArrayLike, cal: LegacyCalibration) -> npt.NDArray[np.float64]:
    """Raw ticks ``(..., n_motors)`` (a scalar for one motor) → degrees (DEGREE) / percent (LINEAR).

    Raises:
        JointOutOfRangeError: With LeRobot's message, outside ±270° / −10..110 %.
    """
    return _one_motor(apply_legacy, raw, cal)


def revert_calibration(values: npt.ArrayLike, cal: LegacyCalibration) -> npt.NDArray[np.int64]:
    """Degrees / percent ``(..., n_motors)`` (a scalar for one motor) → raw ticks, ``np.round`` (half to even)."""
    return _one_motor(revert_legacy, values, cal)


# -------------------------------------------------------------------------------- exact joint map
def degree_joint_map(cal: LegacyCalibration) -> tuple[RobotCalibration, tuple[str, ...]]:
    """The exact joint map of a legacy calibration's DEGREE motors, and the LINEAR motors left out.

    A LeRobot SO-100 file has a LINEAR gripper next to five DEGREE joints; the joints convert exactly (see
    :func:`to_robot_calibration`), the gripper (a percentage of a start..end span) has no joint angle.

    Raises:
        InvalidCalibrationError: Every motor is LINEAR (nothing to convert; all are named).
    """
    if not isinstance(cal, LegacyCalibration):
        raise InvalidCalibrationError(
            f"cal is a {type(cal).__name__}; expected a LegacyCalibration (see read_legacy)"
        )
    keep = [i for i, mode in enumerate(cal.calib_mode) if mode == "DEGREE"]
    linear = tuple(cal.motor_names[i] for i, mode in enumerate(cal.calib_mode) if mode == "LINEAR")
    if not keep:
        raise InvalidCalibrationError(
            f"LINEAR motor(s) {', '.join(linear)} are not convertible to a joint map "
            "(percent of a start..end span, not an angle) and there is no DEGREE motor"
        )
    sub = LegacyCalibration(
        [cal.motor_names[i] for i in keep],
        cal.homing_offset[keep],
        cal.drive_mode[keep],
        cal.start_pos[keep],
        cal.end_pos[keep],
        [cal.calib_mode[i] for i in keep],
    )
    return to_robot_calibration(sub), linear


def to_robot_calibration(cal: LegacyCalibration) -> RobotCalibration:
    """Exact canonical joint map of a legacy DEGREE calibration, in radians.

    Legacy: ``q_rad = (±raw + h)·π/2048``. Canonical: ``q = direction·scale·(raw − homing_offset)`` with
    ``direction = −1 if drive_mode else +1``, ``scale = π/2048`` rad/tick and
    ``homing_offset = −direction·h`` ticks.

    Raises:
        InvalidCalibrationError: Naming every LINEAR motor (a percentage has no joint-angle equivalent).
    """
    linear = [m for m, mode in zip(cal.motor_names, cal.calib_mode, strict=True) if mode == "LINEAR"]
    if linear:
        raise InvalidCalibrationError(
            f"LINEAR motor(s) {', '.join(linear)} are not convertible to a joint map "
            "(percent of a start..end span, not an angle); only DEGREE motors are"
        )
    direction, homing, scale = homing_from_lerobot_legacy(cal.drive_mode, cal.homing_offset)
    return RobotCalibration(cal.motor_names, direction, homing, scale)
