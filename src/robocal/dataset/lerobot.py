"""LeRobot conventions for dataset values: current (normalised) and legacy (degrees / percent).

Current scheme, per motor (normalisation by :mod:`robocal.core.lerobot.normalisation`)::

    value --unnormalize--> present ticks --homing offset in the motor--> actual ticks
    Feetech:   actual = present + homing_offset     (firmware: Present = Actual − Homing_Offset)
    Dynamixel: actual = present − homing_offset     (firmware: Present = Actual + Homing_Offset)

Feetech STS servos report a single-turn position, so a new present position is wrapped into
``[0, resolution)``; Dynamixel arms (Koch) run in extended-position mode and are not wrapped.

Legacy scheme: the offset lived in software only, so present = actual and the value is LeRobot's legacy
``apply_calibration`` (DEGREE or LINEAR, :mod:`robocal.core.lerobot.legacy`).
"""

from __future__ import annotations

import json
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from ..core.arrays import BoolArray, FloatArray
from ..core.lerobot import (
    LEGACY_BOUNDS,
    Compat,
    Convention,
    LegacyCalibration,
    MotorCalibration,
    parse_compat,
    parse_convention,
)
from ..core.lerobot.legacy import revert_calibration
from ..core.lerobot.normalisation import NormMode, normalize, unnormalize
from ..core.profile import RobotProfile
from ..core.vendors import VendorSpec, expected_homing_vendors, homing_vendor, vendor_spec
from ..errors import FileFormatError, InvalidCalibrationError, UsageError
from ..fileio import MAX_DOCUMENT_BYTES, read_text
from ..formats._json import json_int
from ..formats.lerobot import read_current, read_legacy
from ._convention import JointMapConvention, ValueConvention, select_indices

__all__ = [
    "LeRobotConvention",
    "LegacyConvention",
    "MotorFamily",
    "load_convention",
    "motor_family_for_robot",
    "preset_modes",
]

MotorFamily = str
"""A servo vendor's name with a homing rule in :mod:`robocal.core.vendors` (``"feetech"``, ``"dynamixel"``);
checked where a convention is built."""

def _arm_profile(robot: str) -> RobotProfile:
    """The LeRobot arm profile of a robot type: the profile of that name, else one whose ``robot_types`` prefix it.

    The longest prefix wins (e.g. ``so100`` → an SO arm, ``lekiwi`` → the SO-101 follower).

    Raises:
        UsageError: No LeRobot arm profile carries that robot type (the message lists the known prefixes).
    """
    from ..formats.profiles import builtin_lerobot_profiles

    arms = builtin_lerobot_profiles()
    low = robot.lower()
    for p in arms:
        if p.name == low:
            return p
    prefixes = sorted(
        {(t, p.name): p for p in arms if p.lerobot is not None for t in p.lerobot.robot_types}.items(),
        key=lambda item: (-len(item[0][0]), item[0][1]),
    )
    for (prefix, _name), p in prefixes:
        if low.startswith(prefix):
            return p
    known = ", ".join(f"{t}*" for t in sorted({t for (t, _n), _p in prefixes}, key=lambda t: (len(t), t)))
    raise UsageError(f"--robot {robot!r}: unknown robot type; known: {known} (or pass --motor-family)")


def motor_family_for_robot(robot: str) -> MotorFamily:
    """Motor family of a LeRobot robot type, from its arm's profile (``so*`` → Feetech, ``koch*`` → Dynamixel).

    Raises:
        UsageError: Unknown robot type (the message lists the known prefixes).
    """
    lr = _arm_profile(robot).lerobot
    assert lr is not None
    return lr.vendor


def preset_modes(robot: str, joint_names: Sequence[str], use_degrees: bool | None = None) -> dict[str, str]:
    """LeRobot's normalisation mode per joint for a robot preset.

    The robot's arm profile gives the default (``use_degrees`` is on when its arm joints default to
    ``degrees``: SO-100/101 since LeRobot 0.4.4, not Koch); with ``use_degrees`` the arm joints are
    ``degrees``, else ``range_m100_100``; every ``gripper`` (and ``*_gripper``, e.g. LeKiwi's ``arm_gripper``)
    uses ``range_0_100``.

    Args:
        robot: LeRobot robot type, e.g. ``"so101_follower"``, ``"koch_leader"``.
        joint_names: Joints to assign.
        use_degrees: The recording's ``use_degrees`` (``None``: the robot's default).

    Returns:
        Joint name → mode value.
    """
    profile = _arm_profile(robot)
    default = any(j.norm_mode == NormMode.DEGREES.value for j in profile.joints if j.name != "gripper")
    degrees = default if use_degrees is None else use_degrees
    arm = NormMode.DEGREES.value if degrees else NormMode.RANGE_M100_100.value
    return {
        n: (NormMode.RANGE_0_100.value if n == "gripper" or n.endswith("_gripper") else arm)
        for n in joint_names
    }


@dataclass(frozen=True, eq=False)
class LeRobotConvention:
    """Stored values are LeRobot current-scheme normalised positions.

    Attributes:
        joint_names: Motor names in column order.
        calibrations: One :class:`MotorCalibration` per joint.
        modes: One mode value per joint (``"degrees"``, ``"range_m100_100"``, ``"range_0_100"``).
        family: ``"feetech"`` (drive mode in software, offset added) or ``"dynamixel"``.
        compat: ``"lerobot"`` (bit-identical, truncating) or ``"exact"`` (rounding, lossless); rounding only.
        resolution: Ticks per turn.
        wrap: Wrap present positions into ``[0, resolution)`` (default: Feetech yes, Dynamixel no).
        convention: DEGREES as LeRobot records them (``"lerobot"``: 4095 ticks per 360°, drive_mode ignored)
            or ``"physical"`` (4096 ticks per 360°, drive_mode honoured).
    """

    joint_names: tuple[str, ...]
    calibrations: tuple[MotorCalibration, ...]
    modes: tuple[str, ...]
    family: MotorFamily = "feetech"
    compat: Compat = "lerobot"
    resolution: int = 4096
    wrap: bool | None = None
    convention: Convention = "lerobot"

    def __post_init__(self) -> None:
        n = len(self.joint_names)
        if len(self.calibrations) != n or len(self.modes) != n:
            raise InvalidCalibrationError(
                f"LeRobot convention: {n} joints, {len(self.calibrations)} calibrations, "
                f"{len(self.modes)} modes"
            )
        valid = [m.value for m in NormMode]
        for name, mode in zip(self.joint_names, self.modes, strict=True):
            if mode not in valid:
                raise UsageError(f"joint {name!r}: mode {mode!r} is not one of {', '.join(valid)}")
        if homing_vendor(self.family) is None:
            raise UsageError(f"motor family {self.family!r}: expected {expected_homing_vendors(quoted=False)}")
        parse_compat(self.compat, "compat")
        parse_convention(self.convention, "convention")

    @classmethod
    def from_calibrations(
        cls,
        calibrations: Mapping[str, MotorCalibration],
        modes: Mapping[str, str],
        family: MotorFamily,
        compat: Compat = "lerobot",
        convention: Convention = "lerobot",
    ) -> LeRobotConvention:
        """Build from LeRobot's ``{motor: MotorCalibration}`` and ``{motor: mode}``.

        Raises:
            UsageError: A motor has no mode (the message names it).
        """
        names = tuple(calibrations)
        missing = [n for n in names if n not in modes]
        if missing:
            raise UsageError(f"no normalisation mode for {', '.join(missing)}; pass --robot or --modes")
        cals = tuple(calibrations[n] for n in names)
        return cls(names, cals, tuple(modes[n] for n in names), family, compat, convention=convention)

    @property
    def _vendor(self) -> VendorSpec:
        return vendor_spec(self.family)

    @property
    def _apply_drive_mode(self) -> bool:
        return self._vendor.applies_drive_mode_in_software

    @property
    def _wraps(self) -> bool:
        return self._vendor.homing_rule().wraps_per_turn if self.wrap is None else self.wrap

    @property
    def _homing_sign(self) -> float:
        """``Actual = Present + sign · Homing_Offset`` (the inverse of the vendor's homing rule)."""
        return -float(self._vendor.homing_rule().offset_sign)

    def _norm_options(self) -> dict[str, Any]:
        """Keyword arguments of ``normalize`` / ``unnormalize`` for this convention."""
        return {
            "apply_drive_mode": self._apply_drive_mode,
            "compat": self.compat,
            "resolution": self.resolution,
            "convention": self.convention,
        }

    @property
    def _ticks_per_turn_deg(self) -> int:
        """Ticks per 360° of DEGREES values: LeRobot's ``resolution − 1`` or the physical ``resolution``."""
        return self.resolution - 1 if self.convention == "lerobot" else self.resolution

    def _homing(self) -> FloatArray:
        return np.array([c.homing_offset for c in self.calibrations], dtype=np.float64)

    def select(self, joint_names: Sequence[str]) -> LeRobotConvention:
        """Restrict to and reorder as ``joint_names``."""
        idx = select_indices(joint_names, self.joint_names, "LeRobot calibration", "motor")
        return LeRobotConvention(
            tuple(joint_names),
            tuple(self.calibrations[i] for i in idx),
            tuple(self.modes[i] for i in idx),
            self.family,
            self.compat,
            self.resolution,
            self.wrap,
            self.convention,
        )

    @property
    def integer_ticks(self) -> bool:
        """:meth:`to_actual` returns whole ticks (lets the engine map each distinct tick once)."""
        return True

    def check_target(self, new: object) -> None:
        """Refuse a Dynamixel conversion that flips a hardware ``Drive_Mode`` (the files cannot define it).

        Raises:
            UsageError: Naming the joints.
        """
        if not (
            isinstance(new, LeRobotConvention)
            and self.family == new.family
            and self._vendor.drive_mode_in_hardware
        ):
            return
        flipped = [
            n
            for n, a, b in zip(self.joint_names, self.calibrations, new.calibrations, strict=True)
            if a.drive_mode != b.drive_mode
        ]
        if flipped:
            raise UsageError(
                f"Dynamixel drive_mode differs between the calibrations for {', '.join(flipped)}; the "
                "Drive_Mode register changes the encoder reading itself, so this conversion is not defined"
            )

    def _half_tick(self) -> FloatArray:
        """Half a tick in value units, signed so that it moves the unnormalised position up."""
        out = []
        for cal, mode in zip(self.calibrations, self.modes, strict=True):
            inverted = self._apply_drive_mode and bool(cal.drive_mode)
            span = float(cal.range_max - cal.range_min)
            if mode == NormMode.DEGREES.value:
                sign = -1.0 if (inverted and self.convention == "physical") else 1.0
                out.append(sign * 0.5 * 360.0 / self._ticks_per_turn_deg)
            elif mode == NormMode.RANGE_M100_100.value:
                out.append((-1.0 if inverted else 1.0) * 0.5 * 200.0 / span)
            else:
                out.append((-1.0 if inverted else 1.0) * 0.5 * 100.0 / span)
        return np.array(out, dtype=np.float64)

    def to_actual(self, values: FloatArray) -> FloatArray:
        """Normalised values ``(N, D)`` → actual ticks ``(N, D)`` (through LeRobot's ``_unnormalize``).

        Stored values are readings, ``normalize(present)`` of whole ticks kept as float32, so the present
        position is recovered to the *nearest* tick: with ``compat="lerobot"`` the value is moved up by half
        a tick before LeRobot's truncating ``_unnormalize``; ``compat="exact"`` rounds by itself.
        """
        v = np.asarray(values, dtype=np.float64)
        if self.compat == "lerobot":
            v = v + self._half_tick()
        present = unnormalize(v, self.calibrations, self.modes, **self._norm_options()).astype(np.float64)
        actual: FloatArray = present + self._homing_sign * self._homing()
        return actual

    def from_actual(self, actual: FloatArray) -> tuple[FloatArray, BoolArray]:
        """Actual ticks ``(N, D)`` → normalised values and the out-of-range mask.

        The mask marks present positions outside ``[range_min, range_max]`` and, for a single-turn (Feetech)
        motor, positions more than one turn outside ``[0, resolution)`` before wrapping (no pair of
        calibrations with homing offsets within one turn produces those; they are wrapped like the others
        but counted).
        """
        present = np.asarray(actual, dtype=np.float64) - self._homing_sign * self._homing()
        far = np.zeros(present.shape, dtype=np.bool_)
        if self._wraps:
            far = (present < -self.resolution) | (present >= 2 * self.resolution)
            present = np.mod(present, self.resolution)
        lo = np.array([c.range_min for c in self.calibrations], dtype=np.float64)
        hi = np.array([c.range_max for c in self.calibrations], dtype=np.float64)
        mask = (present < lo) | (present > hi) | far
        return normalize(present, self.calibrations, self.modes, **self._norm_options()), mask

    def unrecordable(self, actual: FloatArray) -> BoolArray:
        """Mask of actual positions ``(N, D)`` whose present position no single-turn reading gives.

        A Feetech STS servo reports ``Present_Position`` in ``[0, resolution)``; a stored value whose
        present position (after ``_unnormalize``) lies outside cannot come from one encoder turn (e.g.
        ``1e6`` in degrees mode). The engine counts those as out of range instead of letting the new
        calibration wrap them silently. Always ``False`` for motors that are not wrapped (Dynamixel).
        """
        a = np.asarray(actual, dtype=np.float64)
        if not self._wraps:
            return np.zeros(a.shape, dtype=np.bool_)
        present = a - self._homing_sign * self._homing()
        out: BoolArray = (present < 0) | (present >= self.resolution)
        return out

    def value_range(self) -> tuple[FloatArray, FloatArray] | None:
        """Normalised values of ``range_min`` and ``range_max`` per joint (sorted)."""
        lo = np.array([[c.range_min for c in self.calibrations]], dtype=np.float64)
        hi = np.array([[c.range_max for c in self.calibrations]], dtype=np.float64)
        a, b = (normalize(x, self.calibrations, self.modes, **self._norm_options())[0] for x in (lo, hi))
        return np.minimum(a, b), np.maximum(a, b)

    def full_turn(self) -> FloatArray:
        """Value change per full turn: 360 in degrees mode, ``resolution/(max − min)`` spans otherwise."""
        out = []
        for cal, mode in zip(self.calibrations, self.modes, strict=True):
            span = float(cal.range_max - cal.range_min)
            if mode == NormMode.DEGREES.value:
                out.append(360.0 * self.resolution / self._ticks_per_turn_deg)
            elif mode == NormMode.RANGE_M100_100.value:
                out.append(200.0 * self.resolution / span)
            else:
                out.append(100.0 * self.resolution / span)
        return np.array(out, dtype=np.float64)


@dataclass(frozen=True, eq=False)
class LegacyConvention:
    """Stored values are LeRobot legacy degrees (DEGREE) or percent (LINEAR); present = actual ticks.

    Attributes:
        calibration: The legacy calibration (its ``motor_names`` order is the column order).
        resolution: Ticks per turn.
    """

    calibration: LegacyCalibration
    resolution: int = 4096

    @property
    def joint_names(self) -> tuple[str, ...]:
        """Motor names in column order."""
        return self.calibration.motor_names

    @property
    def integer_ticks(self) -> bool:
        """:meth:`to_actual` returns whole ticks (rounded like LeRobot's ``revert_calibration``)."""
        return True

    def select(self, joint_names: Sequence[str]) -> LegacyConvention:
        """Restrict to and reorder as ``joint_names``."""
        cal = self.calibration
        idx = select_indices(joint_names, cal.motor_names, "legacy calibration", "motor")
        return LegacyConvention(
            LegacyCalibration(
                tuple(joint_names),
                cal.homing_offset[idx],
                cal.drive_mode[idx],
                cal.start_pos[idx],
                cal.end_pos[idx],
                tuple(cal.calib_mode[i] for i in idx),
            ),
            self.resolution,
        )

    def to_actual(self, values: FloatArray) -> FloatArray:
        """Legacy values ``(N, D)`` → ticks (LeRobot's ``revert_calibration``, rounded)."""
        return revert_calibration(values, self.calibration).astype(np.float64)

    def _bounds(self) -> tuple[FloatArray, FloatArray]:
        lo = np.array([LEGACY_BOUNDS[m][0] for m in self.calibration.calib_mode])
        hi = np.array([LEGACY_BOUNDS[m][1] for m in self.calibration.calib_mode])
        return lo, hi

    def from_actual(self, actual: FloatArray) -> tuple[FloatArray, BoolArray]:
        """Ticks ``(N, D)`` → legacy values and the mask of values where LeRobot's legacy read would raise.

        The values are LeRobot's ``apply_calibration`` formula (bit for bit); out-of-range values are converted
        too, instead of raising, and counted.
        """
        cal = self.calibration
        raw = np.asarray(actual, dtype=np.float64)
        linear = np.array([m == "LINEAR" for m in cal.calib_mode])
        span = (cal.end_pos - cal.start_pos).astype(np.float64)
        if np.any(linear & (span == 0)):
            raise InvalidCalibrationError("legacy calibration: start_pos equals end_pos for a LINEAR motor")
        signed = np.where(cal.drive_mode.astype(bool), -raw, raw)
        deg = (signed + cal.homing_offset) / (self.resolution // 2) * 180.0
        with np.errstate(divide="ignore", invalid="ignore"):
            pct = (raw - cal.start_pos) / span * 100.0
        values: FloatArray = np.where(linear, pct, deg)
        lo, hi = self._bounds()
        return values, (values < lo) | (values > hi)

    def unrecordable(self, actual: FloatArray) -> BoolArray:
        """Mask of tick positions ``(N, D)`` LeRobot's legacy read would have refused.

        Beyond ±270° (DEGREE) or −10..110 % (LINEAR): values that cannot come from a recording with this
        calibration.
        """
        return self.from_actual(actual)[1]

    def value_range(self) -> tuple[FloatArray, FloatArray] | None:
        """Legacy bounds: ±270° (DEGREE), −10..110 % (LINEAR)."""
        return self._bounds()

    def full_turn(self) -> FloatArray:
        """360° per turn (DEGREE); ``resolution/|end − start|·100`` % (LINEAR)."""
        cal = self.calibration
        span = np.abs((cal.end_pos - cal.start_pos).astype(np.float64))
        linear = np.array([m == "LINEAR" for m in cal.calib_mode])
        with np.errstate(divide="ignore"):
            out: FloatArray = np.where(linear, 100.0 * self.resolution / span, 360.0)
        return out


def _json_kind(path: Path) -> str | None:
    if path.suffix.lower() != ".json":
        return None
    try:
        data = json.loads(read_text(path, "calibration file", limit=MAX_DOCUMENT_BYTES), parse_int=json_int)
    except (ValueError, RecursionError):  # not JSON (or too deep / too long a number): the reader reports it
        return None
    if isinstance(data, dict) and "motor_names" in data:
        return "legacy"
    if (
        isinstance(data, dict)
        and data
        and all(isinstance(v, dict) and "range_min" in v for v in data.values())
    ):
        return "current"
    return None


def load_convention(
    path: str | Path,
    *,
    joint_names: Sequence[str],
    modes: Mapping[str, str] | None = None,
    family: MotorFamily | None = None,
    compat: Compat = "lerobot",
    what: str = "calibration",
    convention: Convention = "lerobot",
) -> ValueConvention:
    """Read a calibration file as a dataset value convention.

    LeRobot current JSON → :class:`LeRobotConvention` (needs ``modes`` and ``family``); LeRobot legacy JSON
    → :class:`LegacyConvention`; any file :func:`robocal.formats.read_calibration` reads (canonical joint
    maps) → :class:`JointMapConvention` (values are joint-frame radians).

    Args:
        path: The calibration file.
        joint_names: The dataset's joint-position joints (used to pick modes; motors of a LeRobot current
            file that are not among them are left out).
        modes: Joint → mode for LeRobot current files.
        family: Motor family for LeRobot current files.
        compat: LeRobot rounding (``"lerobot"`` truncating, ``"exact"`` rounding).
        what: Role of the file for messages (``"--old"``).
        convention: DEGREES convention of the values (``"lerobot"`` or ``"physical"``).

    Raises:
        FileFormatError: The file is malformed.
        UsageError: A LeRobot current file without modes or motor family.
    """
    p = Path(path)
    if not p.is_file():
        raise FileFormatError(f"{what} {p}: no such file")
    kind = _json_kind(p)
    if kind == "current":
        # motors the dataset does not hold (e.g. LeKiwi's base wheels) are not needed and have no mode
        cals = {n: c for n, c in read_current(p).items() if n in joint_names}
        if family is None:
            raise UsageError(f"{what} {p} is a LeRobot calibration: pass --robot or --motor-family")
        if modes is None:
            raise UsageError(f"{what} {p} is a LeRobot calibration: pass --robot or --modes")
        return LeRobotConvention.from_calibrations(cals, modes, family, compat, convention)
    if kind == "legacy":
        return LegacyConvention(read_legacy(p))
    from ..formats import read_calibration

    cf = read_calibration(p, joint_order=list(joint_names))
    return JointMapConvention(cf.calibration)
