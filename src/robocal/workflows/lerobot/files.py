"""Where a LeRobot arm's calibration file is: ``--file``, else LeRobot's folder (and its pre-v0.4.3 name)."""

from __future__ import annotations

from pathlib import Path

from ...core.lerobot import RobotSpec
from ...errors import UsageError
from ...formats.lerobot import calibration_path

__all__ = ["calibration_file"]


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
