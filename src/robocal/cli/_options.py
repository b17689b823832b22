"""Options several commands share, written once (name, type and help; each command gives the default).

The kinematics commands' own options are in :mod:`._kinematics_options`.
"""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from ..workflows.sweep import DEFAULT_TOPIC

__all__ = ["DEFAULT_TOPIC", "LeRobotCalibrationDir", "LeRobotId", "ReplayFrame", "ReplayTopic"]

ReplayTopic = Annotated[str, typer.Option("--topic", help="JointState topic of a rosbag2 replay.")]
"""``--topic`` of ``check --source``, ``sweep`` and ``view`` (default :data:`DEFAULT_TOPIC`)."""
ReplayFrame = Annotated[
    str | None, typer.Option("--frame", help="Replay positions: identity (default) or motor.")
]
"""``--frame`` of ``check --source`` and ``sweep``."""
LeRobotId = Annotated[str | None, typer.Option("--id", help="Robot id: the calibration is <id>.json.")]
"""``--id`` of the ``lerobot`` commands, ``view --lerobot-port`` and ``kinematics identify``/``record``."""
LeRobotCalibrationDir = Annotated[
    Path | None, typer.Option("--calibration-dir", help="LeRobot calibration root (default: LeRobot's).")
]
"""``--calibration-dir`` of the same commands."""
