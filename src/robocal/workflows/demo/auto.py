"""``robocal demo --auto``: a simulated robot's joints find their own hard stops; true vs recovered zeros.

The ``auto`` job of :data:`robocal.workflows.demo.job.JOBS`. The Lite's 14 Robstride joints are simulated motors on
two ``virtual`` CAN channels, each moving a physics plant on one simulated clock; robocal drives them with MIT
frames through its Robstride bus code (:func:`robocal.workflows.autocal.sweep.run_sweep_auto`, as
``sweep --auto`` does on a real robot).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from pathlib import Path

from ..autocal.model import AutoView
from .job import DemoResult, DemoSection, Say, TruthTable, temporary_note

__all__ = ["AUTO_DEMO_SOURCE", "AUTO_TOLERANCE_RAD", "auto_demo"]

AUTO_DEMO_SOURCE = "sim:lite?seed=0"
"""The ``demo --auto`` Lite's simulated robot."""

AUTO_TOLERANCE_RAD = math.radians(0.5)
"""Largest recovered-offset error ``demo --auto`` accepts, rad."""


def auto_demo(
    robot: str,
    folder: Path,
    say: Say,
    temporary: bool,
    *,
    view: AutoView | None = None,
    view_for: Callable[[Path], AutoView] | None = None,
) -> DemoResult:
    """Auto-calibrate the simulated ``robot`` (``lite``) in ``folder``; compare with the simulator's zeros.

    Args:
        robot: ``lite``, ``so101`` / ``koch`` (:func:`robocal.workflows.demo.auto_arm.auto_arm_demo`) or
            ``openarm`` (:func:`robocal.workflows.demo.auto_openarm.openarm_demo`).
        folder: Folder for the URDF, the calibration and the report (it exists).
        say: Prints progress lines.
        temporary: ``folder`` is removed when the demo returns.
        view: The live view of the stop searches, or None.
        view_for: Instead of ``view``: called with the URDF the demo wrote, returns the live view (a page that
            draws the search on that robot).

    Returns:
        The :class:`~robocal.workflows.demo.job.DemoResult` (``detail``: the
        :class:`~robocal.workflows.autocal.sweep.AutoSweepOutcome`); exit code 0 when every joint passed and
        every recovered zero is within :data:`AUTO_TOLERANCE_RAD` of the truth, else 1.
    """
    if robot == "openarm":  # the simulated OpenArm: sweep --auto --write-zero and LeRobot's file
        from .auto_openarm import openarm_demo

        openarm: DemoResult = openarm_demo(folder, say, temporary, view=view)
        return openarm
    if robot != "lite":  # so101, koch: the LeRobot follower behind the vendor SDK (workflows.demo.auto_arm)
        from .auto_arm import auto_arm_demo

        result: DemoResult = auto_arm_demo(robot, folder, say, temporary, view=view)
        return result
    from ..autocal.sim import SimAutoLite, sim_opener, write_sim_lite_urdf
    from ..autocal.sweep import SweepAutoRequest, run_sweep_auto

    urdf = write_sim_lite_urdf(folder / "lite_bimanual.urdf")
    say(
        "robocal demo --auto: simulated Lite, 14 Robstride joints on two virtual CAN buses, physics on a "
        "simulated clock; each joint finds its own hard stops (no operator)"
    )
    holder: list[SimAutoLite] = []
    outcome = run_sweep_auto(
        SweepAutoRequest(
            urdf,
            AUTO_DEMO_SOURCE,
            folder / "calibration.yaml",
            robot="bhl_arms",
            report=folder / "sweep_report.json",
        ),
        view=view_for(urdf) if view_for is not None else view,
        open_drivers_fn=sim_opener(holder),
    )
    truth = holder[0].true_offsets()
    rows = []
    worst = 0.0
    for j in outcome.result.joints:
        err = j.homing_offset - truth[j.name]
        worst = max(worst, abs(err))
        rows.append((j.name, f"{truth[j.name]:+.4f}", f"{j.homing_offset:+.4f}", f"{math.degrees(err):+.3f}"))
    table = TruthTable(
        "true vs recovered homing_offset (rad)", ("joint", "true", "recovered", "error °"), tuple(rows)
    )
    line = (
        f"largest error {math.degrees(worst):.3f}°, {outcome.auto.total_time_s:.1f} s simulated; wrote "
        f"{outcome.out} and {outcome.report}{temporary_note(temporary)}"
    )
    code = 0 if worst <= AUTO_TOLERANCE_RAD and not outcome.auto.failed else 1
    return DemoResult(
        robot, "auto", folder, temporary, code, outcome, sections=(DemoSection(table),), lines=(line,)
    )
