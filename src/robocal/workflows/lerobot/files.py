"""A LeRobot arm's calibration file: where it is, reading it, its ranges, checking it can be written, its JSON text.

Where: ``--file``, else LeRobot's folder (and, when reading, its pre-v0.4.3 name).
"""

from __future__ import annotations

import os
from collections.abc import Mapping
from pathlib import Path

from ...core.lerobot import MotorCalibration, RobotSpec, ranges_beyond_one_turn
from ...errors import UsageError
from ...fileio import check_output_path
from ...formats.lerobot import calibration_path, dumps_current, read_current

__all__ = [
    "calibration_file",
    "calibration_json",
    "check_calibration_writable",
    "range_warnings",
    "read_calibration_file",
]


def calibration_file(
    spec: RobotSpec,
    robot_id: str | None,
    root: Path | None,
    file: Path | None,
    *,
    reading: bool = True,
) -> tuple[Path, str | None]:
    """The calibration file of an arm, and a warning when the pre-v0.4.3 folder is used.

    ``file`` wins; otherwise LeRobot's ``ROOT/{robots|teleoperators}/<device>/<id>.json``. When reading and that
    file is absent, the folder LeRobot used before v0.4.3 (e.g. ``so101_follower``) is tried.

    Raises:
        UsageError: Neither an id nor a file.
    """
    if file is not None:
        return file, None
    if robot_id is None:
        raise UsageError("give --id (and optionally --calibration-dir) or --file")
    path = calibration_path(spec.kind, spec.device_name, robot_id, root=root)
    if reading and not path.exists() and spec.old_device_name != spec.device_name:
        old = calibration_path(spec.kind, spec.old_device_name, robot_id, root=root)
        if old.exists():
            return old, f"using {old} (LeRobot < 0.4.3 folder); LeRobot now reads {path}"
    return path, None


def read_calibration_file(path: Path) -> dict[str, MotorCalibration]:
    """The calibration LeRobot's JSON file ``path`` holds, per motor (bus order).

    Raises:
        CalibError: The file is missing, unreadable or malformed (the message names it).
    """
    return read_current(path)


def range_warnings(spec: RobotSpec, cals: Mapping[str, MotorCalibration]) -> list[str]:
    """One warning per motor of the arm whose range lies beyond one turn (LeRobot loads such files as they are).

    See :func:`robocal.core.lerobot.ranges_beyond_one_turn`; the messages name the arm's vendor.
    """
    return ranges_beyond_one_turn(cals, vendor=spec.vendor)


def check_calibration_writable(path: str | os.PathLike[str]) -> None:
    """Refuse, before any bus I/O, a calibration file that could not be written (its folder is created).

    Raises:
        CalibError: ``path`` cannot be written (the message starts ``cannot write``).
    """
    check_output_path(path, "cannot write", size_hint=1024, create_dirs=True)


def calibration_json(cals: Mapping[str, MotorCalibration]) -> str:
    """The calibration as LeRobot writes it (``draccus.dump(..., indent=4)``, no final newline)."""
    return dumps_current(cals)
