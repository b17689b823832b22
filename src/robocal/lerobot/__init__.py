"""LeRobot compatibility: current-scheme calibration values, normalisation and files.

>>> cal = MotorCalibration(id=1, drive_mode=0, homing_offset=0, range_min=1000, range_max=3000)
>>> float(normalize(1500, cal, "range_m100_100"))
-50.0

``compat="lerobot"`` is bit-identical to LeRobot 0.6.1; ``compat="exact"`` rounds so raw → normalised → raw
is the identity, and changes nothing else. ``convention="physical"`` (instead of LeRobot's default) makes
DEGREES true joint degrees: 4096 ticks per turn and ``drive_mode`` honoured (see ``docs/lerobot.md``).
"""

from __future__ import annotations

import os
from collections.abc import Callable, Mapping, Sequence
from enum import Enum
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt

from ..core.lerobot import (
    MODE_CODES,
    Compat,
    Convention,
    MotorCalibration,
    _as_float_array,
    normalize_array,
    unnormalize_array,
)
from ..errors import InvalidCalibrationError, ShapeMismatchError, UsageError
from ..formats import lerobot as _fmt

__all__ = [
    "MotorCalibration",
    "NormMode",
    "calibration_path",
    "normalize",
    "read_calibration",
    "unnormalize",
    "write_calibration",
]


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
            mapping (as :func:`read_calibration` returns; taken in its order).
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


def read_calibration(path: str | os.PathLike[str]) -> dict[str, MotorCalibration]:
    """Read a current LeRobot calibration JSON (strict: every field, ints, no extras).

    Raises:
        FileFormatError: Naming the file, motor and field.
    """
    return _fmt.read_current(path)


def write_calibration(path: str | os.PathLike[str], cals: Mapping[str, MotorCalibration]) -> Path:
    """Write a current LeRobot calibration JSON exactly as LeRobot does (4-space indent), atomically.

    Missing parent folders are created; an existing file is kept as ``NAME.bak``.
    """
    return _fmt.write_current(path, cals)


KINDS = {
    "robots": "robots",
    "robot": "robots",
    "teleoperators": "teleoperators",
    "teleoperator": "teleoperators",
}


def default_calibration_root() -> Path:
    """LeRobot's calibration root folder.

    ``$HF_LEROBOT_CALIBRATION``, else ``$HF_LEROBOT_HOME/calibration``, else ``$HF_HOME/lerobot/calibration``
    where ``HF_HOME`` defaults like ``huggingface_hub`` to ``$XDG_CACHE_HOME/huggingface``, else
    ``~/.cache/huggingface`` (so ``~/.cache/huggingface/lerobot/calibration``). Empty variables count as unset.
    """
    env = os.environ
    if env.get("HF_LEROBOT_CALIBRATION"):
        return Path(env["HF_LEROBOT_CALIBRATION"]).expanduser()
    if env.get("HF_LEROBOT_HOME"):
        return Path(env["HF_LEROBOT_HOME"]).expanduser() / "calibration"
    if env.get("HF_HOME"):
        hf_home = Path(os.path.expandvars(os.path.expanduser(env["HF_HOME"])))
    else:
        cache = Path(env["XDG_CACHE_HOME"]) if env.get("XDG_CACHE_HOME") else Path.home() / ".cache"
        hf_home = Path(os.path.expandvars(os.path.expanduser(cache / "huggingface")))
    return hf_home / "lerobot" / "calibration"


def calibration_path(
    kind: str, name: str, id: str | None, root: str | os.PathLike[str] | None = None
) -> Path:
    """LeRobot's calibration file path ``ROOT/{robots|teleoperators}/<name>/<id>.json``.

    Args:
        kind: ``"robots"`` or ``"teleoperators"`` (singular accepted).
        name: Device class name, e.g. ``"so_follower"`` (v0.4.3+), ``"so101_follower"`` (older),
            ``"koch_leader"``.
        id: The robot id; ``None`` gives LeRobot's literal ``None.json``.
        root: Calibration root; default :func:`default_calibration_root`.
    """
    if kind not in KINDS:
        raise UsageError(f"calibration kind {kind!r}: expected 'robots' or 'teleoperators'")
    for what, value in (("name", name), ("id", str(id))):
        if not value or "/" in value or "\\" in value or value in (".", ".."):
            raise UsageError(f"calibration {what} {value!r}: expected a plain file name")
    base = Path(root).expanduser() if root is not None else default_calibration_root()
    return base / KINDS[kind] / name / f"{id}.json"
