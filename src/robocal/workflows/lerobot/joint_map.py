"""The exact URDF joint map of a LeRobot arm's DEGREES joints (``robocal lerobot export-urdf``)."""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from pathlib import Path

from ...core.jointmap import RobotCalibration
from ...core.lerobot import (
    MotorCalibration,
    RobotSpec,
)
from ...errors import InvalidCalibrationError, UsageError
from ...fileio import check_output_path
from ...formats import write_calibration
from .arms import norm_modes

__all__ = [
    "export_joint_map",
    "write_joint_map",
]


def check_joint_map_out(out: Path, calibration_file: Path | None) -> None:
    """Refuse, before the calibration is read, an ``--out`` that cannot be written or is the ``--file`` it reads.

    Raises:
        FileWriteError: Naming the problem (a ``UsageError``: exit 2, nothing written).
    """
    check_output_path(out, "--out", inputs={"--file": calibration_file})


def write_joint_map(out: Path, joint_map: RobotCalibration, ids: Mapping[str, int]) -> None:
    """Write the joint map as robocal's canonical YAML, atomically with a ``.bak``, with each joint's motor id."""
    write_calibration(out, joint_map, "robocal", ids=ids)


def export_joint_map(
    spec: RobotSpec,
    cals: Mapping[str, MotorCalibration],
    *,
    signs: Mapping[str, int] | None = None,
    offsets_deg: Mapping[str, float] | None = None,
    compat: str = "lerobot",
    modes: Sequence[str] | None = None,
    convention: str = "lerobot",
) -> tuple[RobotCalibration, list[str]]:
    """Exact canonical joint map ``q_urdf = sign·q_lerobot + offset`` of the DEGREES joints (#4442).

    LeRobot DEGREES: ``q = (present − mid)·360/4095`` (``convention="lerobot"``) or ``·360/4096`` with
    drive_mode (``"physical"``), ``mid = (range_min + range_max)/2``. Canonical form
    ``q_rad = d·k·(present − h)`` with ``d = sign·(−1 if physical and drive_mode else 1)``, ``k = 2π/4095``
    (or ``2π/4096``) rad/tick and ``h = mid − offset_rad/(d·k)``. ``present`` is the Present_Position register
    (EEPROM homing applied). ``compat`` only changes rounding to whole ticks, which a joint map does not do, so
    it does not change the map (it is still checked).

    ``modes`` is the norm mode per motor in bus order (default: the robot's, see :func:`norm_modes`).

    Returns:
        The joint map (radians) of the DEGREES motors and the names of the skipped (range-mode) motors.
    """
    from ...core.lerobot import parse_compat, parse_convention

    parse_compat(compat, "compat")
    physical = parse_convention(convention, "convention") == "physical"
    signs = dict(signs or {})
    offsets_deg = dict(offsets_deg or {})
    unknown = sorted((set(signs) | set(offsets_deg)) - set(spec.motor_names))
    if unknown:
        raise UsageError(f"--sign/--offset name unknown motor(s) {', '.join(unknown)}")
    for name, value in signs.items():
        if value not in (-1, 1):
            raise UsageError(f"--sign {name}={value}: expected -1 or 1")
    mode_of = dict(zip(spec.motor_names, modes if modes is not None else norm_modes(spec), strict=True))
    names, dirs, homes, scales, skipped = [], [], [], [], []
    for m in spec.motors:
        if m.name not in cals:
            raise InvalidCalibrationError(f"calibration has no entry for motor {m.name!r}")
        if mode_of[m.name] != "degrees":
            skipped.append(m.name)
            continue
        c = cals[m.name]
        s = signs.get(m.name, 1)
        ticks = 4096 if physical else 4095
        d = s * (-1 if (physical and c.drive_mode and spec.vendor_spec.applies_drive_mode_in_software) else 1)
        k = 2 * math.pi / ticks
        mid = (c.range_min + c.range_max) / 2
        off_rad = math.radians(offsets_deg.get(m.name, 0.0))
        names.append(m.name)
        dirs.append(float(d))
        homes.append(mid - off_rad / (d * k))
        scales.append(k)
    if not names:
        raise InvalidCalibrationError(f"{spec.name}: no DEGREES motors to export")
    return RobotCalibration(names, dirs, homes, scales), skipped
