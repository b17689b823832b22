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

from typing import Literal, cast, get_args

import numpy as np
import numpy.typing as npt

from ...errors import InvalidCalibrationError, ShapeMismatchError, UsageError
from ._values import FloatArray, IntArray, _as_float_array, _check_resolution, _check_values, _to_ticks

__all__ = [
    "MODE_CODES",
    "Compat",
    "Convention",
    "normalize_array",
    "parse_compat",
    "parse_convention",
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
