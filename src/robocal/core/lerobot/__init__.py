"""LeRobot motor calibration math, pure numpy: one module per job.

* :mod:`.registers` — Feetech sign-magnitude and Dynamixel two's complement register encodings;
* :mod:`.calibration` — :class:`MotorCalibration` (a motor's entry of LeRobot's calibration JSON) and its checks;
* :mod:`.normalisation` — raw ticks ↔ LeRobot's normalised values (current #777 → v0.6.1 scheme);
* :mod:`.homing` — the half-turn homing offset and the centring of a swept travel;
* :mod:`.legacy` — the 2024 legacy scheme (six parallel arrays, DEGREE/LINEAR);
* :mod:`.arm` — :class:`RobotSpec`, a LeRobot arm built from its robot profile.

Everything is vectorised over a trailing motor axis: ``raw`` has shape ``(..., n_motors)`` and the per-motor
parameters have shape ``(n_motors,)``. Positions are servo ticks (``raw_ticks``), 4096 per turn unless stated.
The names below are re-exported so ``from robocal.core.lerobot import normalize_array`` keeps working.
"""

from __future__ import annotations

from ..arrays import FloatArray, IntArray
from ._values import _as_float_array, _check_resolution, _check_values, _to_ticks
from .arm import LeRobotMotor, RobotSpec
from .calibration import MotorCalibration, ranges_beyond_one_turn
from .homing import centre_homing, half_turn_homing_offset, offset_in_register, wrap_feetech_offset
from .legacy import (
    HALF_TURN_DEGREE,
    LEGACY_BOUNDS,
    LOWER_BOUND_DEGREE,
    LOWER_BOUND_LINEAR,
    UPPER_BOUND_DEGREE,
    UPPER_BOUND_LINEAR,
    LegacyCalibration,
    apply_legacy,
    autocorrect_legacy,
    avoid_rotation_reset,
    degree_joint_map,
    degrees_to_steps,
    legacy_calibration_from_poses,
    nearest_rounded_position,
    revert_legacy,
    to_robot_calibration,
)
from .normalisation import (
    MODE_CODES,
    Compat,
    Convention,
    NormMode,
    normalize,
    normalize_array,
    parse_compat,
    parse_convention,
    unnormalize,
    unnormalize_array,
)
from .registers import (
    decode_sign_magnitude,
    decode_twos_complement,
    encode_sign_magnitude,
    encode_twos_complement,
)

__all__ = [
    "HALF_TURN_DEGREE",
    "LEGACY_BOUNDS",
    "LOWER_BOUND_DEGREE",
    "LOWER_BOUND_LINEAR",
    "MODE_CODES",
    "UPPER_BOUND_DEGREE",
    "UPPER_BOUND_LINEAR",
    "Compat",
    "Convention",
    "FloatArray",
    "IntArray",
    "LeRobotMotor",
    "LegacyCalibration",
    "MotorCalibration",
    "NormMode",
    "RobotSpec",
    "_as_float_array",
    "_check_resolution",
    "_check_values",
    "_to_ticks",
    "apply_legacy",
    "autocorrect_legacy",
    "avoid_rotation_reset",
    "centre_homing",
    "decode_sign_magnitude",
    "decode_twos_complement",
    "degree_joint_map",
    "degrees_to_steps",
    "encode_sign_magnitude",
    "encode_twos_complement",
    "half_turn_homing_offset",
    "legacy_calibration_from_poses",
    "nearest_rounded_position",
    "normalize",
    "normalize_array",
    "offset_in_register",
    "parse_compat",
    "parse_convention",
    "ranges_beyond_one_turn",
    "revert_legacy",
    "to_robot_calibration",
    "unnormalize",
    "unnormalize_array",
    "wrap_feetech_offset",
]
