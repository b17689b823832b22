"""LeRobot's current-scheme normalisation (#777 → v0.6.1), pure numpy: raw ticks ↔ normalised values.

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

from collections.abc import Callable, Mapping, Sequence
from enum import Enum
from typing import Any, Literal, cast, get_args

import numpy as np
import numpy.typing as npt

from ...errors import InvalidCalibrationError, ShapeMismatchError, UsageError
from ..arrays import FloatArray, IntArray
from ._values import _as_float_array, _check_resolution, _check_values, _to_ticks
from .calibration import MotorCalibration

__all__ = [
    "MODE_CODES",
    "Compat",
    "Convention",
    "NormMode",
    "normalize",
    "normalize_array",
    "parse_compat",
    "parse_convention",
    "unnormalize",
    "unnormalize_array",
]


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


def _inputs(
    x_in: npt.ArrayLike,
    what: str,
    range_min: npt.ArrayLike,
    range_max: npt.ArrayLike,
    drive_mode: npt.ArrayLike,
    modes: npt.ArrayLike,
    apply_drive_mode: bool,
    resolution: int,
) -> tuple[FloatArray, FloatArray, FloatArray, npt.NDArray[np.bool_], IntArray, int]:
    """``(x, range_min, range_max, inverted, mode codes, resolution)`` checked in this order.

    ``inverted`` is ``drive_mode`` where ``apply_drive_mode`` holds.
    """
    lo, hi, dm, mc = _params(range_min, range_max, drive_mode, modes)
    resolution = _check_resolution(resolution)
    x = _check_values(x_in, lo.shape[0], what)
    return x, lo, hi, dm & bool(apply_drive_mode), mc, resolution


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
    x, lo, hi, dm, mc, resolution = _inputs(
        raw_ticks, "raw", range_min, range_max, drive_mode, mode_codes, apply_drive_mode, resolution
    )
    per_turn, dm_deg = _degrees_setup(dm, compat, convention, resolution)
    out: FloatArray = np.empty(x.shape)
    for code, cols in _mode_groups(mc):
        xs = x[..., cols]  # a view for a run of columns
        if code == 2:  # DEGREES: (x − mid) · 360 / per_turn, negated for an inverted motor
            buf = np.subtract(xs, ((lo + hi) / 2)[cols])
            buf *= 360
            buf /= per_turn
            _flip(buf, dm_deg[cols], 0.0)
        else:  # the ranges: frac = (clip(x) − lo) / (hi − lo); frac·200 − 100 or frac·100 (100 − that inverted)
            buf = np.maximum(xs, lo[cols])
            np.minimum(buf, hi[cols], out=buf)
            buf -= lo[cols]
            buf /= (hi - lo)[cols]
            if code == 0:
                buf *= 200
                buf -= 100
                _flip(buf, dm[cols], 0.0)
            else:
                buf *= 100
                _flip(buf, dm[cols], 100.0)
        out[..., cols] = buf
    return out


def _mode_groups(mc: IntArray) -> list[tuple[int, slice | IntArray]]:
    """``(mode code, its columns)`` for each mode present: a slice for a run of columns, else their indices."""
    groups: list[tuple[int, slice | IntArray]] = []
    for code in (0, 1, 2):
        idx = np.flatnonzero(mc == code)
        if idx.size:
            run = idx[-1] - idx[0] + 1 == idx.size
            groups.append((code, slice(int(idx[0]), int(idx[-1]) + 1) if run else idx))
    return groups


def _flip(buf: FloatArray, inverted: npt.NDArray[np.bool_], around: float) -> None:
    """``around − buf`` in place in the inverted columns (−buf for ``around`` 0; IEEE: the same bits)."""
    if inverted.any():
        sign = np.where(inverted, -1.0, 1.0)
        buf *= sign
        if around:
            buf += np.where(inverted, around, 0.0)


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
    v, lo, hi, dm, mc, resolution = _inputs(
        values, "values", range_min, range_max, drive_mode, mode_codes, apply_drive_mode, resolution
    )
    per_turn, dm_deg = _degrees_setup(dm, compat, convention, resolution)
    out: FloatArray = np.empty(v.shape)
    for code, cols in _mode_groups(mc):
        buf = np.array(v[..., cols])
        if code == 2:  # DEGREES: v · per_turn / 360 + mid (v negated for an inverted motor)
            _flip(buf, dm_deg[cols], 0.0)
            buf *= per_turn
            buf /= 360
            buf += ((lo + hi) / 2)[cols]
        else:  # the ranges: clip, (v + 100) / 200 or v / 100, · (hi − lo) + lo (−v or 100 − v inverted)
            _flip(buf, dm[cols], 0.0 if code == 0 else 100.0)
            np.maximum(buf, -100.0 if code == 0 else 0.0, out=buf)
            np.minimum(buf, 100.0, out=buf)
            if code == 0:
                buf += 100
                buf /= 200
            else:
                buf /= 100
            buf *= (hi - lo)[cols]
            buf += lo[cols]
        out[..., cols] = buf
    if compat == "lerobot":
        np.trunc(out, out=out)
    else:  # half away from zero
        away = np.abs(out)
        away += 0.5
        np.floor(away, out=away)
        out = np.copysign(away, out, out=away)
    return _to_ticks(out, "values")


# ------------------------------------------------------------------ per-motor dispatch (public API)
class NormMode(str, Enum):
    """LeRobot ``MotorNormMode``; plain strings with these values are accepted everywhere."""

    RANGE_M100_100 = "range_m100_100"
    RANGE_0_100 = "range_0_100"
    DEGREES = "degrees"


CalibrationArg = MotorCalibration | Sequence[MotorCalibration] | Mapping[str, MotorCalibration]
ModeArg = NormMode | str | Sequence[NormMode | str] | Mapping[str, NormMode | str]


def _mode_code(mode: object) -> int:
    value = mode.value if isinstance(mode, NormMode) else mode
    if not isinstance(value, str) or value not in MODE_CODES:
        raise InvalidCalibrationError(f"norm mode {mode!r}: expected one of {', '.join(MODE_CODES)}")
    return MODE_CODES[value]


def _unpack(calibration: CalibrationArg, mode: ModeArg) -> tuple[bool, list[MotorCalibration], list[int]]:
    """``(one motor, calibrations, mode codes)``; a Mapping (as read from a file) is taken in its order."""
    single = isinstance(calibration, MotorCalibration)
    if isinstance(calibration, MotorCalibration):
        cals = [calibration]
    elif isinstance(calibration, Mapping):
        cals = list(calibration.values())
    elif isinstance(calibration, (str, bytes)):
        cals = []
    else:
        try:
            cals = list(calibration)
        except TypeError:
            cals = []
    if not cals or not all(isinstance(c, MotorCalibration) for c in cals):
        raise InvalidCalibrationError(
            "calibration: expected a MotorCalibration or a non-empty sequence of them"
        )
    if isinstance(mode, (str, NormMode)):
        codes = [_mode_code(mode)] * len(cals)
    elif isinstance(mode, Mapping):
        if not isinstance(calibration, Mapping):
            raise InvalidCalibrationError(
                "modes given by motor name need the calibration as a motor name → MotorCalibration mapping "
                "(as read_calibration returns); with a sequence of calibrations give one mode per motor in order"
            )
        names = list(calibration)
        missing = [n for n in names if n not in mode]
        unknown = [str(n) for n in mode if n not in calibration]
        if missing or unknown:
            parts = []
            if missing:
                parts.append(f"no mode for motor(s) {', '.join(map(str, missing))}")
            if unknown:
                parts.append(f"mode(s) for unknown motor(s) {', '.join(unknown)}")
            raise ShapeMismatchError(f"modes by motor name: {'; '.join(parts)}")
        codes = []
        for n in names:
            try:
                codes.append(_mode_code(mode[n]))
            except InvalidCalibrationError as exc:
                raise InvalidCalibrationError(f"motor {n!r}: {exc}") from None
    else:
        try:
            modes = list(mode)
        except TypeError:
            raise InvalidCalibrationError(
                f"norm mode {mode!r}: expected one of {', '.join(MODE_CODES)} or one per motor"
            ) from None
        codes = [_mode_code(m) for m in modes]
        if len(codes) != len(cals):
            raise ShapeMismatchError(
                f"{len(codes)} modes for {len(cals)} motors; expected one mode per motor"
            )
    return single, cals, codes


def _per_motor(
    kernel: Callable[..., npt.NDArray[Any]],
    what: str,
    x_in: npt.ArrayLike,
    calibration: CalibrationArg,
    mode: ModeArg,
    **options: Any,
) -> npt.NDArray[Any]:
    """Run a vectorised kernel over the motor axis; one motor (or a scalar for one motor) gets its own."""
    single, cals, codes = _unpack(calibration, mode)
    x = _as_float_array(x_in, what)
    add_axis = single or (len(cals) == 1 and x.ndim == 0)
    if add_axis:
        x = x[..., np.newaxis]
    out = kernel(
        x,
        [c.range_min for c in cals],
        [c.range_max for c in cals],
        [c.drive_mode for c in cals],
        codes,
        **options,
    )
    return out[..., 0] if add_axis else out


def normalize(
    raw: npt.ArrayLike,
    calibration: CalibrationArg,
    mode: ModeArg,
    *,
    apply_drive_mode: bool = True,
    compat: Compat = "lerobot",
    resolution: int = 4096,
    convention: Convention = "lerobot",
) -> npt.NDArray[np.float64]:
    """Raw ``Present_Position`` ticks → LeRobot normalised values (LeRobot's ``_normalize``).

    Args:
        raw: Decoded ticks, shape ``(..., n_motors)``, or a scalar for one motor; with a single
            ``MotorCalibration`` any shape (each element is that motor).
        calibration: One ``MotorCalibration``, a sequence of one per motor, or a motor name → calibration
            mapping (as ``robocal.lerobot.read_calibration`` returns; taken in its order).
        mode: One mode for all motors, one per motor in order, or (with a name → calibration mapping) a
            motor name → mode mapping naming every motor (``NormMode`` or its string value).
        apply_drive_mode: True for Feetech (software inversion), False for Dynamixel (hardware Drive_Mode).
        compat: Rounding only: ``"lerobot"`` truncates like LeRobot 0.6.1, ``"exact"`` rounds (lossless).
            Normalising does not round, so both give the same values here.
        resolution: Ticks per turn (4096; scs0009 1024).
        convention: DEGREES scale and sign: ``"lerobot"`` (LeRobot's ``resolution − 1`` ticks per 360°,
            drive_mode ignored) or ``"physical"`` (``resolution`` ticks per 360°, drive_mode honoured).

    Returns:
        Float64 array of ``raw``'s shape: −100..100, 0..100 or degrees.

    Raises:
        InvalidCalibrationError: Input that is not real numbers (strings, also number strings; booleans;
            complex; datetime64; ``None``, reported as missing), NaN/inf, an unknown mode, a drive_mode other
            than 0/1, ``range_min >= range_max``.
        ShapeMismatchError: The last axis is not the number of motors, or the modes do not match the motors.
    """
    return _per_motor(
        normalize_array,
        "raw",
        raw,
        calibration,
        mode,
        apply_drive_mode=apply_drive_mode,
        compat=compat,
        resolution=resolution,
        convention=convention,
    )


def unnormalize(
    values: npt.ArrayLike,
    calibration: CalibrationArg,
    mode: ModeArg,
    *,
    apply_drive_mode: bool = True,
    compat: Compat = "lerobot",
    resolution: int = 4096,
    convention: Convention = "lerobot",
) -> npt.NDArray[np.int64]:
    """Normalised values → raw ``Goal_Position`` ticks (LeRobot's ``_unnormalize``); see :func:`normalize`.

    Returns:
        Int64 array of ``values``' shape (truncated like ``int()`` with ``compat="lerobot"``, rounded with
        ``"exact"``; otherwise the same values).
    """
    return _per_motor(
        unnormalize_array,
        "values",
        values,
        calibration,
        mode,
        apply_drive_mode=apply_drive_mode,
        compat=compat,
        resolution=resolution,
        convention=convention,
    )
