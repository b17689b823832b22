"""LeRobot motor calibration math, pure numpy (current #777 → v0.6.1 scheme and the 2024 legacy scheme).

Everything is vectorised over a trailing motor axis: ``raw`` has shape ``(..., n_motors)`` and the per-motor
parameters have shape ``(n_motors,)``. Positions are servo ticks (``raw_ticks``), 4096 per turn unless stated.

Two independent choices:

* ``compat`` changes rounding only. ``"lerobot"`` reproduces LeRobot 0.6.1's ``_normalize`` /
  ``_unnormalize`` bit for bit: the same float operations in the same order and ``int()`` truncation toward
  zero. ``"exact"`` rounds to the nearest tick instead (so raw → normalised → raw is the identity for every
  tick in range); it gives LeRobot's values up to that truncation (the same scale and sign rules).
* ``convention`` chooses the DEGREES scale and sign. ``"lerobot"`` (default) is LeRobot's: ``resolution − 1``
  (4095) ticks per 360° and ``drive_mode`` ignored. ``"physical"`` uses ``resolution`` (4096) ticks per 360° and
  honours ``drive_mode`` (with ``apply_drive_mode``), so degrees are true joint degrees; values then differ
  from LeRobot's (a drive_mode-1 Feetech motor has the opposite sign).
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any, Literal, cast, get_args

import numpy as np
import numpy.typing as npt

from ..errors import InvalidCalibrationError, JointOutOfRangeError, ShapeMismatchError, UsageError
from .profile import RobotProfile

__all__ = [
    "LEGACY_BOUNDS",
    "MODE_CODES",
    "LeRobotMotor",
    "LegacyCalibration",
    "MotorCalibration",
    "RobotSpec",
    "apply_legacy",
    "autocorrect_legacy",
    "avoid_rotation_reset",
    "centre_homing",
    "decode_sign_magnitude",
    "decode_twos_complement",
    "degrees_to_steps",
    "encode_sign_magnitude",
    "encode_twos_complement",
    "half_turn_homing_offset",
    "legacy_calibration_from_poses",
    "nearest_rounded_position",
    "normalize_array",
    "ranges_beyond_one_turn",
    "revert_legacy",
    "unnormalize_array",
]

FloatArray = npt.NDArray[np.float64]
IntArray = npt.NDArray[np.int64]
Compat = Literal["lerobot", "exact"]
Convention = Literal["lerobot", "physical"]


def _parse_choice(value: str, choices: tuple[str, ...], what: str) -> str:
    """``value`` when it is one of ``choices``.

    Raises:
        UsageError: Any other value (the message names ``what`` and the choices).
    """
    if value in choices:
        return value
    raise UsageError(f"{what} {value!r}: expected {' or '.join(choices)}")


def parse_compat(value: str, what: str = "--compat") -> Compat:
    """Check a compat name: ``"lerobot"`` (bit-identical to LeRobot) or ``"exact"`` (lossless).

    Raises:
        UsageError: Any other value (the message names ``what``).
    """
    return cast(Compat, _parse_choice(value, get_args(Compat), what))


def parse_convention(value: str, what: str = "convention") -> Convention:
    """Check a DEGREES convention name: ``"lerobot"`` (4095 ticks per turn, no drive_mode) or ``"physical"``.

    Raises:
        UsageError: Any other value (the message names ``what``).
    """
    return cast(Convention, _parse_choice(value, get_args(Convention), what))


MODE_CODES: dict[str, int] = {"range_m100_100": 0, "range_0_100": 1, "degrees": 2}
"""LeRobot norm-mode value → integer code used in the vectorised kernels."""


@dataclass(frozen=True)
class MotorCalibration:
    """One motor's current-scheme LeRobot calibration (the values of LeRobot's calibration JSON).

    Attributes:
        id: Bus id of the motor.
        drive_mode: 0 or 1 (1 = inverted; Feetech in software, Dynamixel in the Drive_Mode register).
        homing_offset: Homing_Offset register value, ticks (signed).
        range_min: Min_Position_Limit, ticks.
        range_max: Max_Position_Limit, ticks.
    """

    id: int
    drive_mode: int
    homing_offset: int
    range_min: int
    range_max: int

    def __post_init__(self) -> None:
        for field in ("id", "drive_mode", "homing_offset", "range_min", "range_max"):
            value = getattr(self, field)
            if isinstance(value, bool) or not isinstance(value, (int, np.integer)):
                raise InvalidCalibrationError(f"MotorCalibration.{field} is {value!r}; expected an int")
            object.__setattr__(self, field, int(value))


def ranges_beyond_one_turn(
    cals: Mapping[str, MotorCalibration], *, resolution: int = 4096, vendor: str = "feetech"
) -> list[str]:
    """One warning per motor whose ``range_min..range_max`` lies outside one turn ``0..resolution − 1``.

    A single-turn servo (Feetech STS/SMS; Dynamixel X in position mode) never reports a Present_Position
    outside ``0..resolution − 1``, and its Min/Max_Position_Limit registers hold positions of that turn. LeRobot
    0.6.1 does not check this: it loads such a file, writes the values to the limit registers as they are and
    normalises with them, so the part of the range beyond the turn is never reached (a RANGE_0_100 gripper with
    range 3441..4837 tops out at 47 %). robocal accepts the file the same way but names every such motor.

    Args:
        cals: Motor name → calibration.
        resolution: Ticks per turn (4096).
        vendor: ``"feetech"`` or ``"dynamixel"`` (only used in the message).

    Returns:
        ``"motor 'NAME' (id N): range_min..range_max LO..HI is beyond one turn ..."`` per motor, in file order.
    """
    out = []
    top = resolution - 1
    for name, c in cals.items():
        if c.range_min >= 0 and c.range_max <= top:
            continue
        span = c.range_max - c.range_min
        reach = ""
        if span > 0 and c.range_min <= top and c.range_max >= 0:
            lo_pct = 100.0 * (max(c.range_min, 0) - c.range_min) / span
            hi_pct = 100.0 * (min(c.range_max, top) - c.range_min) / span
            reach = f"; positions of one turn only cover {lo_pct:.0f}..{hi_pct:.0f} % of it"
        out.append(
            f"motor {name!r} (id {c.id}): range_min..range_max {c.range_min}..{c.range_max} is beyond one turn "
            f"of a {resolution}-tick {vendor} servo (0..{top}){reach}; LeRobot 0.6.1 accepts it unchecked; "
            "recalibrate the motor (or re-home the range)"
        )
    return out


# ------------------------------------------------------------------------------------------------ encodings
def encode_sign_magnitude(value: int, sign_bit_index: int) -> int:
    """Feetech sign-magnitude encoding: ``((value < 0) << k) | |value|``.

    Raises:
        InvalidCalibrationError: ``|value| > 2**k − 1`` (LeRobot's message).
    """
    max_magnitude = (1 << sign_bit_index) - 1
    magnitude = abs(int(value))
    if magnitude > max_magnitude:
        raise InvalidCalibrationError(
            f"Magnitude {magnitude} exceeds {max_magnitude} (max for sign_bit_index={sign_bit_index})"
        )
    direction_bit = 1 if value < 0 else 0
    return (direction_bit << sign_bit_index) | magnitude


def decode_sign_magnitude(encoded: int, sign_bit_index: int) -> int:
    """Inverse of :func:`encode_sign_magnitude`; bits above ``k`` are ignored and "−0" is 0."""
    magnitude = int(encoded) & ((1 << sign_bit_index) - 1)
    return -magnitude if (int(encoded) >> sign_bit_index) & 1 else magnitude


def encode_twos_complement(value: int, n_bytes: int) -> int:
    """Dynamixel two's complement of ``value`` in ``n_bytes`` bytes.

    Raises:
        InvalidCalibrationError: value outside ``[−2**(8n−1), 2**(8n−1) − 1]`` (LeRobot's message).
    """
    bits = 8 * n_bytes
    lo, hi = -(1 << (bits - 1)), (1 << (bits - 1)) - 1
    v = int(value)
    if not lo <= v <= hi:
        raise InvalidCalibrationError(
            f"Value {v} out of range for {n_bytes}-byte two's complement: [{lo}, {hi}]"
        )
    return v & ((1 << bits) - 1)


def decode_twos_complement(encoded: int, n_bytes: int) -> int:
    """Inverse of :func:`encode_twos_complement`."""
    bits = 8 * n_bytes
    v = int(encoded) & ((1 << bits) - 1)
    return v - (1 << bits) if v & (1 << (bits - 1)) else v


# --------------------------------------------------------------------------------------- current scheme
def _params(
    range_min: npt.ArrayLike, range_max: npt.ArrayLike, drive_mode: npt.ArrayLike, modes: npt.ArrayLike
) -> tuple[FloatArray, FloatArray, npt.NDArray[np.bool_], IntArray]:
    lo = np.atleast_1d(_as_float_array(range_min, "range_min"))
    hi = np.atleast_1d(_as_float_array(range_max, "range_max"))
    dm_raw = np.atleast_1d(_as_float_array(drive_mode, "drive_mode"))
    mc = np.atleast_1d(np.asarray(modes, dtype=np.int64))
    n = lo.shape[0]
    for name, arr in (("range_max", hi), ("drive_mode", dm_raw), ("mode", mc)):
        if arr.shape != (n,):
            raise ShapeMismatchError(f"{name} has shape {arr.shape}; expected ({n},) like range_min")
    for name, arr in (("range_min", lo), ("range_max", hi)):
        if not np.all(np.isfinite(arr)):
            raise InvalidCalibrationError(f"{name} {arr.tolist()}: expected finite ticks")
    bad_dm = [i for i in range(n) if dm_raw[i] not in (0.0, 1.0)]
    if bad_dm:
        i = bad_dm[0]
        raise InvalidCalibrationError(
            f"Invalid calibration for motor {i}: drive_mode is {dm_raw[i]:g}; expected 0 or 1"
        )
    dm = dm_raw.astype(bool)
    for i in range(n):
        if lo[i] == hi[i]:
            raise InvalidCalibrationError(f"Invalid calibration for motor {i}: min and max are equal.")
        if lo[i] > hi[i]:
            raise InvalidCalibrationError(
                f"Invalid calibration for motor {i}: range_min {lo[i]:g} is greater than range_max {hi[i]:g}."
            )
    if np.any((mc < 0) | (mc > 2)):
        raise InvalidCalibrationError(f"mode codes {mc.tolist()}: expected 0, 1 or 2")
    return lo, hi, dm, mc


def _check_resolution(resolution: int) -> int:
    if isinstance(resolution, bool) or not isinstance(resolution, (int, np.integer)) or resolution < 2:
        raise InvalidCalibrationError(f"resolution {resolution!r}: expected ticks per turn, an int >= 2")
    return int(resolution)


_NUMERIC_KINDS = "iuf"
_KIND_NAMES = {
    "b": "booleans",
    "c": "complex numbers",
    "M": "datetime64 values",
    "m": "timedelta64 values",
    "U": "strings",
    "S": "byte strings",
    "V": "structured values",
}


def _as_float_array(x: npt.ArrayLike, what: str) -> FloatArray:
    """``x`` as float64, or an InvalidCalibrationError naming ``what`` and what was found.

    Only real numbers are taken (ints, floats, numpy integer/float arrays). Refused: strings (also number
    strings such as ``"1500"``), booleans, complex numbers, datetime64/timedelta64, ``None`` (reported as a
    missing value), ragged lists and any other object.
    """
    try:
        with np.errstate(invalid="ignore"):
            probe = np.asarray(x)
    except (TypeError, ValueError, OverflowError):
        raise InvalidCalibrationError(f"{what} is not an array of numbers: {x!r:.80}") from None
    kind = probe.dtype.kind
    if kind == "O":
        flat = probe.reshape(-1)
        missing = [i for i, v in enumerate(flat) if v is None]
        if missing:
            where = f" (element {missing[0]})" if probe.ndim else ""
            raise InvalidCalibrationError(f"{what} has a missing value (None){where}; expected numbers")
        for v in flat:
            if isinstance(v, (bool, np.bool_)) or not isinstance(v, (int, float, np.integer, np.floating)):
                raise InvalidCalibrationError(
                    f"{what} contains {type(v).__name__} {v!r:.40}; expected real numbers"
                )
        try:
            probe = probe.astype(np.float64)
        except (TypeError, ValueError, OverflowError):
            raise InvalidCalibrationError(f"{what} is not an array of numbers: {x!r:.80}") from None
    elif kind not in _NUMERIC_KINDS:
        name = _KIND_NAMES.get(kind, f"dtype {probe.dtype}")
        raise InvalidCalibrationError(f"{what} contains {name} ({x!r:.60}); expected real numbers")
    with np.errstate(invalid="ignore", over="ignore"):
        arr: FloatArray = probe.astype(np.float64)
    return arr


def _to_ticks(x: npt.NDArray[np.floating[Any]], what: str) -> IntArray:
    """Whole-valued float ticks → int64, refusing values an int64 cannot hold (instead of wrapping)."""
    if np.any(np.abs(x) >= 2.0**63):
        raise InvalidCalibrationError(
            f"{what}: the resulting ticks exceed the int64 range (largest |value| {np.max(np.abs(x)):g})"
        )
    return x.astype(np.int64)


def _check_values(x: npt.ArrayLike, n: int, what: str) -> FloatArray:
    arr = _as_float_array(x, what)
    if arr.ndim == 0 or arr.shape[-1] != n:
        raise ShapeMismatchError(f"{what} has shape {arr.shape}; expected (..., {n}) for {n} motor(s)")
    if not np.all(np.isfinite(arr)):
        raise InvalidCalibrationError(f"{what} contains NaN or inf; expected finite numbers")
    return arr


def _degrees_setup(
    dm: npt.NDArray[np.bool_], compat: str, convention: str, resolution: int
) -> tuple[int, npt.NDArray[np.bool_]]:
    """Ticks per 360° and the DEGREES inversion mask of a convention (compat is only validated here)."""
    if compat not in ("lerobot", "exact"):
        raise InvalidCalibrationError(f"compat {compat!r}: expected 'lerobot' or 'exact'")
    if convention == "lerobot":
        return resolution - 1, np.zeros_like(dm)
    if convention == "physical":
        return resolution, dm
    raise InvalidCalibrationError(f"convention {convention!r}: expected 'lerobot' or 'physical'")


def normalize_array(
    raw_ticks: npt.ArrayLike,
    range_min: npt.ArrayLike,
    range_max: npt.ArrayLike,
    drive_mode: npt.ArrayLike,
    mode_codes: npt.ArrayLike,
    *,
    apply_drive_mode: bool = True,
    compat: Compat = "lerobot",
    resolution: int = 4096,
    convention: Convention = "lerobot",
) -> FloatArray:
    """Raw ticks → LeRobot normalised values.

    Args:
        raw_ticks: Shape ``(..., n)``, decoded (signed) ``Present_Position`` ticks.
        range_min: Shape ``(n,)``, ticks.
        range_max: Shape ``(n,)``, ticks.
        drive_mode: Shape ``(n,)``, 0 or 1.
        mode_codes: Shape ``(n,)``, see :data:`MODE_CODES`.
        apply_drive_mode: LeRobot's bus attribute (True for Feetech, False for Dynamixel).
        compat: ``"lerobot"`` or ``"exact"``; normalising does not round, so both give the same values.
        resolution: Ticks per turn (4096; scs0009 1024).
        convention: DEGREES as LeRobot (``"lerobot"``: ``resolution − 1`` ticks per 360°, drive_mode
            ignored) or ``"physical"`` (``resolution`` ticks per 360°, drive_mode honoured).

    Returns:
        Shape ``(..., n)`` float64: −100..100, 0..100 or degrees.
    """
    lo, hi, dm_in, mc = _params(range_min, range_max, drive_mode, mode_codes)
    resolution = _check_resolution(resolution)
    x = _check_values(raw_ticks, lo.shape[0], "raw")
    dm = dm_in & bool(apply_drive_mode)
    bounded = np.minimum(hi, np.maximum(lo, x))
    frac = (bounded - lo) / (hi - lo)
    m100 = frac * 200 - 100
    m100 = np.where(dm, -m100, m100)
    p100 = frac * 100
    p100 = np.where(dm, 100 - p100, p100)
    mid = (lo + hi) / 2
    per_turn, dm_deg = _degrees_setup(dm, compat, convention, resolution)
    deg = (x - mid) * 360 / per_turn
    deg = np.where(dm_deg, -deg, deg)
    out: FloatArray = np.where(mc == 0, m100, np.where(mc == 1, p100, deg))
    return out


def unnormalize_array(
    values: npt.ArrayLike,
    range_min: npt.ArrayLike,
    range_max: npt.ArrayLike,
    drive_mode: npt.ArrayLike,
    mode_codes: npt.ArrayLike,
    *,
    apply_drive_mode: bool = True,
    compat: Compat = "lerobot",
    resolution: int = 4096,
    convention: Convention = "lerobot",
) -> IntArray:
    """LeRobot normalised values → raw ticks (inverse of :func:`normalize_array`).

    ``compat="lerobot"`` truncates toward zero like ``int()``; ``"exact"`` rounds half away from zero. That is
    the only difference; ``convention`` chooses the DEGREES scale and sign (see :func:`normalize_array`).

    Returns:
        Shape ``(..., n)`` int64 ticks (DEGREES is not clamped and may be negative).
    """
    lo, hi, dm_in, mc = _params(range_min, range_max, drive_mode, mode_codes)
    resolution = _check_resolution(resolution)
    v = _check_values(values, lo.shape[0], "values")
    dm = dm_in & bool(apply_drive_mode)
    vm = np.where(dm, -v, v)
    m100 = (np.minimum(100.0, np.maximum(-100.0, vm)) + 100) / 200 * (hi - lo) + lo
    vp = np.where(dm, 100 - v, v)
    p100 = np.minimum(100.0, np.maximum(0.0, vp)) / 100 * (hi - lo) + lo
    mid = (lo + hi) / 2
    per_turn, dm_deg = _degrees_setup(dm, compat, convention, resolution)
    vd = np.where(dm_deg, -v, v)
    deg = vd * per_turn / 360 + mid
    out = np.where(mc == 0, m100, np.where(mc == 1, p100, deg))
    if compat == "lerobot":
        return _to_ticks(np.trunc(out), "values")
    return _to_ticks(np.sign(out) * np.floor(np.abs(out) + 0.5), "values")


def half_turn_homing_offset(
    present_ticks: int,
    *,
    vendor: Literal["feetech", "dynamixel"],
    resolution: int = 4096,
    compat: Compat = "exact",
) -> int:
    """Homing offset that makes the held pose read half a turn (``set_half_turn_homings``).

    Feetech firmware: ``Present = Actual − Homing_Offset`` → ``offset = pos − (res−1)//2``. Dynamixel:
    ``Present = Actual + Homing_Offset`` → ``offset = (res−1)//2 − pos``. The pose must be read after
    ``reset_calibration`` (offset 0), so Present = Actual.

    With ``compat="lerobot"`` a Feetech pose at 4095 gives +2048, which the sign-magnitude register cannot
    hold (LeRobot crashes with "Magnitude 2048 exceeds 2047"). The default ``"exact"`` first wraps the pose
    into ``[0, res)`` (multi-turn feedback) and clamps the Feetech offset to ±(res/2 − 1),
    so that pose reads 2048.

    Raises:
        InvalidCalibrationError: ``compat="lerobot"`` and the Feetech offset is not encodable.
    """
    half = (resolution - 1) // 2
    pos = int(present_ticks)
    if vendor == "feetech":
        if compat == "lerobot":
            offset = pos - half
            encode_sign_magnitude(offset, 11)
            return offset
        offset = pos % resolution - half
        limit = resolution // 2 - 1
        return max(-limit, min(limit, offset))
    if vendor == "dynamixel":
        return half - pos
    raise InvalidCalibrationError(f"vendor {vendor!r}: expected 'feetech' or 'dynamixel'")


def centre_homing(min_unwrapped: int, max_unwrapped: int, *, resolution: int = 4096) -> tuple[int, int, int]:
    """Shift that centres a swept travel on the half turn, so the seam lies outside it (fixes #3587).

    Args:
        min_unwrapped: Smallest unwrapped Present reading, ticks (may be < 0).
        max_unwrapped: Largest unwrapped Present reading, ticks (may be > resolution − 1).
        resolution: Ticks per turn.

    Returns:
        ``(shift, range_min, range_max)``: readings must be lowered by ``shift`` ticks (Feetech: add ``shift``
        to Homing_Offset; Dynamixel: subtract it), after which the travel is ``range_min..range_max`` inside
        ``[0, resolution − 1]``. A travel of a full turn or more gives ``0..resolution − 1``.
    """
    lo, hi = int(min_unwrapped), int(max_unwrapped)
    if hi - lo >= resolution - 1:
        shift = (lo + hi) // 2 - (resolution - 1) // 2
        return shift, 0, resolution - 1
    centre = (lo + hi) // 2
    shift = centre - (resolution - 1) // 2
    return shift, lo - shift, hi - shift


# ---------------------------------------------------------------------------------------- legacy scheme
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
    vendor: Literal["feetech", "dynamixel"],
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
    if vendor == "dynamixel":
        nearest = nearest_rounded_position(rot_driven, resolution)
    elif vendor == "feetech":
        nearest = rot_driven
    else:
        raise InvalidCalibrationError(f"vendor {vendor!r}: expected 'feetech' or 'dynamixel'")
    homing = quarter - nearest
    if calib_mode is None:
        modes = ["LINEAR" if (vendor == "feetech" and m == "gripper") else "DEGREE" for m in motor_names]
    else:
        modes = list(calib_mode)
    return LegacyCalibration(motor_names, homing, drive_mode, zero, rot_driven, modes)


# ------------------------------------------------------------------------------------------ robot specs
@dataclass(frozen=True)
class LeRobotMotor:
    """One motor of a LeRobot arm: name, bus id, model, LeRobot norm mode and legacy calibration mode."""

    name: str
    motor_id: int
    model: str
    norm_mode: str
    legacy_mode: str = "DEGREE"


@dataclass(frozen=True)
class RobotSpec:
    """A LeRobot arm as its calibration sees it (built from its robot profile by :meth:`from_profile`).

    Attributes:
        name: robocal / LeRobot CLI name (``"so101_follower"``).
        device_name: LeRobot class ``name`` used in the calibration path (``"so_follower"`` since v0.4.3).
        old_device_name: The directory name before v0.4.3 (``"so101_follower"``).
        kind: ``"robots"`` or ``"teleoperators"``.
        vendor: ``"feetech"`` or ``"dynamixel"``.
        motors: Motors in bus order.
        full_turn: Motors LeRobot does not sweep (forced to ``0..resolution − 1``).
        operating_mode: Operating_Mode written before calibrating.
        inverted: Motors whose drive_mode is 1 (Koch leader ``elbow_flex``).
    """

    name: str
    device_name: str
    old_device_name: str
    kind: str
    vendor: Literal["feetech", "dynamixel"]
    motors: tuple[LeRobotMotor, ...]
    full_turn: tuple[str, ...]
    operating_mode: int
    inverted: tuple[str, ...] = ()

    @property
    def motor_names(self) -> tuple[str, ...]:
        """Motor names in bus order."""
        return tuple(m.name for m in self.motors)

    @classmethod
    def from_profile(cls, profile: RobotProfile) -> RobotSpec:
        """The LeRobot arm of a robot profile with a ``lerobot`` section (see ``docs/profiles.md``).

        Raises:
            UsageError: The profile is not a LeRobot arm (no ``lerobot`` section).
        """
        lr = profile.lerobot
        if lr is None:
            raise UsageError(f"robot profile {profile.name} is not a LeRobot arm (it has no lerobot section)")
        motors = []
        for j in profile.joints:
            if j.motor_id is None or j.model is None or j.norm_mode is None:  # pragma: no cover - parser checks
                raise UsageError(f"robot profile {profile.name}: joint {j.name} lacks id, model or norm_mode")
            motors.append(LeRobotMotor(j.name, j.motor_id, j.model, j.norm_mode, j.legacy_mode or "DEGREE"))
        return cls(
            profile.name,
            lr.device_name,
            lr.old_device_name,
            lr.kind,
            cast(Literal["feetech", "dynamixel"], lr.vendor),
            tuple(motors),
            lr.full_turn,
            lr.operating_mode,
            lr.inverted,
        )
