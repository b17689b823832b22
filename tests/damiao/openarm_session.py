"""Shared set-up of the OpenArm tests: robocal's right-arm URDF and joints, a session's calibration file, and one
``sweep --auto`` session on the simulated arm whose simulators are closed however it ends."""

from __future__ import annotations

import contextlib
import math
from collections.abc import Iterator, Mapping
from importlib import resources
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from robocal.core.jointmap import RobotCalibration
from robocal.formats.calibration._base import CalibrationFile

if TYPE_CHECKING:  # the session's modules are imported by the session (python-can only where a test runs one)
    from robocal.workflows.autocal.damiao import SimAutoOpenArm
    from robocal.workflows.autocal.sweep import AutoSweepOutcome, SweepAutoRequest

URDF = Path(str(resources.files("robocal").joinpath("data", "openarm_v10_right.urdf")))
RIGHT = [f"openarm_right_joint{i}" for i in range(1, 8)] + ["openarm_right_gripper_motor"]


def session_file(offset_deg: float = 0.0, ranges_rad: Mapping[str, tuple[float, float]] | None = None) -> CalibrationFile:
    """The right arm's calibration after a session: every offset ``offset_deg``, the measured ``ranges_rad``."""
    cal = RobotCalibration(RIGHT, np.ones(8), np.full(8, math.radians(offset_deg)))
    return CalibrationFile(cal, {}, "robocal", ranges_rad=dict(ranges_rad or {}))


@contextlib.contextmanager
def openarm_session(request: SweepAutoRequest) -> Iterator[tuple[AutoSweepOutcome, SimAutoOpenArm]]:
    """Run ``request`` (a ``sim:openarm`` source) on the simulated arm; its outcome and the arm, closed on exit."""
    from robocal.workflows.autocal.damiao import sim_openarm_opener
    from robocal.workflows.autocal.sweep import run_sweep_auto

    holder: list[SimAutoOpenArm] = []
    try:
        outcome = run_sweep_auto(request, open_drivers_fn=sim_openarm_opener(holder))
        yield outcome, holder[0]
    finally:
        for sim in holder:
            sim.close()
