"""Legacy (2024) LeRobot calibration → the current scheme, keeping each DEGREE joint's zero exactly."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

from ...core.lerobot import (
    LegacyCalibration,
    MotorCalibration,
    centre_homing,
    offset_in_register,
)
from ...core.vendors import expected_homing_vendors, homing_vendor
from ...errors import InvalidCalibrationError, UsageError
from ...formats.lerobot import read_legacy, write_current

__all__ = [
    "legacy_to_current",
    "migrate_file",
]


def migrate_file(
    legacy_file: Path, vendor: str, ids: Sequence[int] | None = None, out: Path | None = None
) -> tuple[dict[str, MotorCalibration], list[str]]:
    """Read a legacy calibration file, convert it (:func:`legacy_to_current`) and write it to ``out`` if given.

    ``out`` is written atomically with a ``.bak``, after everything was read and checked.

    Returns:
        The current calibration and the conversion's warnings.
    """
    cals, warnings = legacy_to_current(read_legacy(legacy_file), vendor, ids)
    if out is not None:
        write_current(out, cals)
    return cals, warnings


def legacy_to_current(
    legacy_cal: object, vendor: str, ids: Sequence[int] | None = None
) -> tuple[dict[str, MotorCalibration], list[str]]:
    """Convert a legacy calibration to the current format, keeping each DEGREE joint's zero exactly.

    The current DEGREES zero is the middle of ``range_min..range_max``. robocal picks range 0..4094 (middle
    2047) and the Homing_Offset that makes legacy 0° read 2047: Feetech ``H = −h − 2047`` (wrapped to ±2047),
    Dynamixel ``H = h + 2047`` (Drive_Mode carries the inversion). Remaining difference: LeRobot's DEGREES
    scale is 360/4095 per tick instead of the legacy 360/4096 (0.024 %). LINEAR joints keep
    ``start_pos..end_pos`` as their range.

    Returns:
        The current calibration and warnings (Feetech inverted DEGREE joints: LeRobot's DEGREES ignores
        drive_mode).
    """
    if not isinstance(legacy_cal, LegacyCalibration):
        raise UsageError("legacy_to_current needs a LegacyCalibration")
    spec = homing_vendor(vendor)
    if spec is None:
        raise UsageError(f"vendor {vendor!r}: expected {expected_homing_vendors()}")
    rule = spec.homing_rule()
    n = len(legacy_cal.motor_names)
    motor_ids = list(ids) if ids is not None else list(range(1, n + 1))
    if len(motor_ids) != n:
        raise UsageError(f"{len(motor_ids)} ids for {n} motors")
    seen: set[int] = set()
    for i in motor_ids:
        if isinstance(i, bool) or not isinstance(i, int) or not 0 <= i <= 253:
            raise UsageError(f"--ids: motor id {i} is outside 0..253")
        if i in seen:
            raise UsageError(f"--ids: motor id {i} is given twice")
        seen.add(i)
    out: dict[str, MotorCalibration] = {}
    warnings: list[str] = []
    for k, name in enumerate(legacy_cal.motor_names):
        h = int(legacy_cal.homing_offset[k])
        dm = int(legacy_cal.drive_mode[k])
        if legacy_cal.calib_mode[k] == "LINEAR":
            start, end = int(legacy_cal.start_pos[k]), int(legacy_cal.end_pos[k])
            lo, hi = sorted((start, end))
            if lo == hi:
                raise InvalidCalibrationError(f"motor {name!r}: LINEAR start_pos equals end_pos ({lo})")
            # legacy percent = (raw − start)/(end − start): 0 % at start_pos. With start > end the percentage
            # falls as the reading rises; Feetech's software drive_mode 1 (100 − n) keeps that exactly.
            lin_dm = 0
            if start > end:
                if spec.applies_drive_mode_in_software:
                    lin_dm = 1
                else:
                    warnings.append(
                        f"{name}: legacy LINEAR start_pos {start} > end_pos {end} (0 % at the higher reading); "
                        f"RANGE_0_100 on {spec.title} counts from range_min, so this joint's percentage is reversed"
                    )
            offset = 0
            if lo < 0 or hi > 4095:  # legacy Feetech readings were unwrapped past the 0/4095 seam
                if hi - lo >= 4095:
                    raise InvalidCalibrationError(
                        f"motor {name!r}: LINEAR start_pos..end_pos {lo}..{hi} spans {hi - lo} ticks, a full turn "
                        "or more of a 4096-tick servo; no range of one turn holds it (recalibrate this motor)"
                    )
                shift, new_lo, new_hi = centre_homing(lo, hi, resolution=4096)
                offset, new_lo, new_hi = offset_in_register(rule, rule.offset_for_shift(0, shift), new_lo, new_hi, 4096)
                warnings.append(
                    f"{name}: legacy LINEAR range {lo}..{hi} goes beyond one turn of a 4096-tick servo "
                    f"(0..4095); re-homed to homing_offset {offset}, range {new_lo}..{new_hi} (the same travel; "
                    "write it to the motor with `robocal lerobot calibrate --use-file`)"
                )
                lo, hi = new_lo, new_hi
            out[name] = MotorCalibration(motor_ids[k], lin_dm, offset, lo, hi)
            continue
        offset = rule.offset_sign * (h + 2047)  # legacy 0° reads 2047
        if rule.wraps_per_turn:
            offset = (offset + 2048) % 4096 - 2048
            if offset == -2048:
                offset = -2047
                warnings.append(f"{name}: offset clamped by one tick")
        if dm and spec.applies_drive_mode_in_software:
            warnings.append(
                f"{name}: inverted (drive_mode 1) but LeRobot's DEGREES ignores drive_mode on {spec.title}; "
                "the sign of this joint flips"
            )
        out[name] = MotorCalibration(motor_ids[k], dm, offset, 0, 4094)
    return out, warnings
