"""Live normalised positions of a LeRobot arm (``robocal lerobot show``)."""

from __future__ import annotations

import os
from collections.abc import Iterator, Mapping, Sequence

from ...backends.servo_bus import ServoBus
from ...core.lerobot import Compat, Convention, MotorCalibration, RobotSpec, normalize
from ...errors import UsageError

__all__ = ["read_positions", "require_motors"]


def require_motors(
    spec: RobotSpec, cals: Mapping[str, MotorCalibration], path: str | os.PathLike[str] | None = None
) -> None:
    """Refuse a calibration that lacks one of the arm's motors (``path``: its file, named in the message).

    Raises:
        UsageError: Naming every motor without an entry.
    """
    missing = [n for n in spec.motor_names if n not in cals]
    if missing:
        where = "calibration" if path is None else f"calibration {os.fspath(path)}"
        raise UsageError(f"{where} has no entry for motor(s) {', '.join(missing)}")


def read_positions(
    bus: ServoBus,
    spec: RobotSpec,
    cals: Mapping[str, MotorCalibration],
    modes: Sequence[str],
    *,
    samples: int,
    compat: Compat = "lerobot",
    convention: Convention = "lerobot",
) -> Iterator[tuple[float, ...]]:
    """Read Present_Position ``samples`` times and normalise it like LeRobot (one value per motor, bus order).

    Args:
        bus: The arm's open bus.
        spec: The arm.
        cals: Its calibration (every motor; see :func:`require_motors`).
        modes: Norm mode per motor in bus order.
        samples: Number of readings.
        compat: Rounding (normalising does not round; kept for the same options as LeRobot's bus).
        convention: DEGREES as LeRobot (``"lerobot"``) or physical degrees (``"physical"``).

    Yields:
        One tuple of normalised values per reading.
    """
    require_motors(spec, cals)
    order = [cals[n] for n in spec.motor_names]
    ids = [m.motor_id for m in spec.motors]
    for _ in range(samples):
        raw = bus.sync_read("Present_Position", ids)
        values = normalize(
            [raw[i] for i in ids],
            order,
            list(modes),
            apply_drive_mode=spec.vendor_spec.applies_drive_mode_in_software,
            compat=compat,
            convention=convention,
        )
        yield tuple(float(v) for v in values)
