"""``robocal demo --robot openarm --auto``: the simulated OpenArm v10 calibrates itself and gets LeRobot's file.

One session, as ``robocal sweep --auto --write-zero --format openarm-lerobot`` runs it on a real arm: the right arm's
eight simulated Damiao motors (``sim:openarm``: MIT law, TIMEOUT, state codes, flash; physics with gravity, friction,
backlash, metal and printed stops on one simulated clock) are driven through robocal's ``DamiaoBus`` into both
stops of every joint, each joint's zero is stored in its motor (0xFE), and LeRobot's ``openarm_follower``
calibration file is written with the measured ranges. The truth table sets the simulator's stops and the motors'
zero errors beside LeRobot's own procedure on the same arm (the person's hanging pose, ±90° for every joint).
"""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

__all__ = ["OPENARM_DEMO_SOURCE", "OPENARM_ZERO_TOLERANCE_DEG", "openarm_demo"]

OPENARM_DEMO_SOURCE = "sim:openarm?seed=0"
"""The demo's simulated arm."""
OPENARM_ZERO_TOLERANCE_DEG = 0.1
"""Largest zero error the demo accepts: every joint must read its true angle within this (LeRobot's bar)."""


def openarm_demo(folder: Path, say: Any, temporary: bool, *, view: Any = None) -> Any:
    """Calibrate the simulated right arm in ``folder``; the truth beside what LeRobot will read.

    Returns:
        A :class:`~robocal.workflows.demo.job.DemoResult` (job ``auto``; ``detail`` the
        :class:`~robocal.workflows.autocal.sweep.AutoSweepOutcome`); exit code 0 when every joint passed and every
        motor's zero is within :data:`OPENARM_ZERO_TOLERANCE_DEG` of its joint's 0, else 1.
    """
    from ...backends.damiao.openarm_urdf import openarm_urdf_text
    from ...fileio import atomic_write_text
    from ...formats.lerobot import calibration_path
    from ..autocal.damiao import SimAutoOpenArm, sim_openarm_opener
    from ..autocal.sweep import SweepAutoRequest, run_sweep_auto
    from .job import DemoResult, DemoSection, TruthTable, temporary_note

    urdf = folder / "openarm_v10_right.urdf"
    atomic_write_text(urdf, openarm_urdf_text("right"), backup=False)
    out = calibration_path("robots", "openarm_follower", "demo", root=folder)
    out.parent.mkdir(parents=True, exist_ok=True)
    say(
        "robocal demo --auto: simulated OpenArm v10 (right arm), 8 Damiao motors on a virtual CAN bus, physics on a "
        "simulated clock; every joint finds both its stops, its zero is stored in its motor, LeRobot's file written"
    )
    holder: list[SimAutoOpenArm] = []
    outcome = run_sweep_auto(
        SweepAutoRequest(
            urdf,
            OPENARM_DEMO_SOURCE,
            out,
            robot="openarm_follower_right",
            report=folder / "sweep_report.json",
            fmt="openarm-lerobot",
            write_zero=True,
        ),
        view=view,
        open_drivers_fn=sim_openarm_opener(holder),
    )
    arm = holder[0].arm
    lerobot = json.loads(out.read_text(encoding="utf-8"))
    rows = []
    worst = 0.0
    for j in arm.joints:
        err = math.degrees(arm.zero_error_rad(j.name))
        worst = max(worst, abs(err))
        lo, hi = math.degrees(j.stop_lower_rad), math.degrees(j.stop_upper_rad)
        rows.append(
            (
                j.name,
                f"{lo:+.0f} … {hi:+.0f}",
                f"{lerobot[j.name]['range_min']:+d} … {lerobot[j.name]['range_max']:+d}",
                f"{err:+.3f}",
                f"{-math.degrees(j.rest_rad) + 0.0:+.2f} (−90 … +90)",
            )
        )
    table = TruthTable(
        "simulated stops and what LeRobot will read (degrees)",
        ("motor", "true stops", "file's range", "zero error", "LeRobot's own: zero error (range)"),
        tuple(rows),
    )
    line = (
        f"largest zero error {worst:.3f}° (each motor's stored zero vs its joint's 0, one flash write each), "
        f"{outcome.auto.total_time_s:.0f} s simulated; wrote {out} (LeRobot openarm_follower, id demo) and "
        f"{outcome.report}{temporary_note(temporary)}"
    )
    code = 0 if worst <= OPENARM_ZERO_TOLERANCE_DEG and not outcome.auto.failed else 1
    return DemoResult(
        "openarm", "auto", folder, temporary, code, outcome, sections=(DemoSection(table),), lines=(line,)
    )
