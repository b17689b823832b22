"""Options several commands share, written once (name, type and help; each command gives the default).

The kinematics commands' own options are in :mod:`._kinematics_options`.
"""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from ._catalog import DEFAULT_TOPIC, robot_profile_names

__all__ = [
    "DEFAULT_TOPIC",
    "LeRobotArm",
    "LeRobotCalibrationDir",
    "LeRobotCompat",
    "LeRobotId",
    "LeRobotModes",
    "LeRobotPhysical",
    "LeRobotUseDegrees",
    "ReplayFrame",
    "ReplayTopic",
    "RobotProfile",
]

RobotProfile = Annotated[
    str | None,
    typer.Option(
        "--robot",
        help="Robot profile: a built-in name ("
        + ", ".join(robot_profile_names())
        + ") or a profile YAML file (docs/profiles.md). Default: the built-in robot the URDF's joint names match.",
    ),
]
"""``--robot`` of ``convert``, ``check`` and ``sweep``."""
ReplayTopic = Annotated[str, typer.Option("--topic", help="JointState topic of a rosbag2 replay.")]
"""``--topic`` of ``check --source``, ``sweep`` and ``view`` (default :data:`DEFAULT_TOPIC`)."""
ReplayFrame = Annotated[
    str | None, typer.Option("--frame", help="Replay positions: identity (default) or motor.")
]
"""``--frame`` of ``check --source`` and ``sweep``."""
LeRobotArm = Annotated[
    str | None, typer.Option("--robot", help="LeRobot robot type (so101_follower, koch_follower, ...).")
]
"""``--robot`` of the ``dataset`` commands (optional)."""
LeRobotId = Annotated[str | None, typer.Option("--id", help="Robot id: the calibration is <id>.json.")]
"""``--id`` of the ``lerobot`` commands, ``view --lerobot-port`` and ``kinematics identify``/``record``."""
LeRobotCalibrationDir = Annotated[
    Path | None, typer.Option("--calibration-dir", help="LeRobot calibration root (default: LeRobot's).")
]
"""``--calibration-dir`` of the same commands."""

# LeRobot's number conventions, of ``lerobot show``/``export-urdf`` and ``dataset recalibrate``/``renormalize``.
LeRobotUseDegrees = Annotated[
    bool | None,
    typer.Option(
        "--use-degrees/--no-use-degrees",
        help="LeRobot's use_degrees: joints in DEGREES or RANGE_M100_100 (gripper RANGE_0_100). "
        "Default as LeRobot: SO arms degrees, Koch not.",
    ),
]
LeRobotModes = Annotated[
    str | None,
    typer.Option(
        "--modes",
        help="Norm mode per joint, overriding the rest: name=degrees|range_m100_100|range_0_100,...",
    ),
]
LeRobotCompat = Annotated[
    str,
    typer.Option(
        "--compat",
        help="Rounding only: lerobot (truncating, bit-identical) or exact (nearest tick, lossless).",
    ),
]
"""``--compat`` (default ``"lerobot"``)."""
LeRobotPhysical = Annotated[
    bool,
    typer.Option(
        "--physical",
        help="Degrees as physical joint degrees (4096 ticks per turn, drive_mode honoured) instead of "
        "LeRobot's (4095, drive_mode ignored).",
    ),
]
