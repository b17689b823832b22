"""``robocal demo --auto --robot so101`` (or ``koch``): a simulated LeRobot follower finds its own hard stops.

The arm's servos are simulated behind a pseudo-terminal with their firmware (Feetech STS3215 position servo with
``Torque_Limit``; Dynamixel current-based position with ``Goal_Current``) moving a joint plant each on one
simulated clock; robocal drives them through the unmodified vendor SDK exactly as ``robocal lerobot calibrate
--auto`` does (:func:`robocal.workflows.lerobot.auto.auto_calibrate`) and writes LeRobot's JSON. The truth table
sets the simulator's stops beside the ones recovered from the written calibration. Joints the profile gives no
stop (the Koch's full-turn ``shoulder_pan`` and ``wrist_roll``) are reported ``not_searched`` and keep their
calibration.
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import Any

__all__ = ["AUTO_ARM_PORT", "AUTO_ARM_ROBOTS", "AUTO_ARM_TOLERANCE_TICKS", "auto_arm_demo"]

AUTO_ARM_ROBOTS: dict[str, str] = {"so101": "so101_follower", "koch": "koch_follower"}
"""``demo --auto`` robot → the LeRobot follower it simulates."""
AUTO_ARM_PORT = "sim"
"""The simulated arm (its default truth: zeros and stops, ``lerobot calibrate --auto --port sim``)."""
AUTO_ARM_TOLERANCE_TICKS = 3
"""Largest recovered hard-stop error the demo accepts, ticks (0.26° on a 4096-tick encoder)."""


def auto_arm_demo(
    robot: str, folder: Path, say: Callable[[str], None], temporary: bool, *, view: Any = None
) -> Any:
    """Auto-calibrate the simulated follower of ``robot`` (``so101`` or ``koch``); recovered vs true stops.

    Returns:
        A :class:`~robocal.workflows.demo.job.DemoResult` (job ``auto``; ``detail`` the
        :class:`~robocal.workflows.lerobot.auto.AutoCalibrationResult`); exit code 0 when every searched joint
        passed and every recovered stop is within :data:`AUTO_ARM_TOLERANCE_TICKS` of the truth, else 1.
    """
    from ...formats.lerobot import calibration_path
    from ..lerobot import robot_spec
    from ..lerobot.auto import AutoCalibrationRequest, auto_calibrate, auto_section
    from ..lerobot.auto_sim import open_auto_arm, sim_gravity_model
    from .job import DemoResult, DemoSection, TruthTable, temporary_note

    name = AUTO_ARM_ROBOTS[robot]
    spec = robot_spec(name)
    section = auto_section(name)
    moving = [j.name for j in section.searched_joints]
    say(
        f"robocal demo --auto: simulated {name}, {len(spec.motors)} {spec.vendor} servos behind the real SDK on a "
        f"pseudo-terminal, physics on a simulated clock; {', '.join(moving)} find their own hard stops "
        "(no operator)"
    )
    path = calibration_path(spec.kind, spec.device_name, "demo", root=folder)
    with open_auto_arm(spec, AUTO_ARM_PORT, section) as arm:
        result = auto_calibrate(
            arm.bus,
            AutoCalibrationRequest(
                spec,
                section,
                path=path,
                gravity_model=sim_gravity_model(spec),
            ),
            clock=arm.clock,
            view=view,
        )
        stops = arm.sim.recovered_stops(result.calibration)
        truth = dict(arm.sim.truth)
        res = {m.name: arm.sim.servo(m.name).resolution for m in spec.motors}
    ok = not result.auto.failed
    rows = []
    for outcome in result.auto.joints:
        n = outcome.name
        tr = truth[n]
        if not outcome.ok:
            rows.append((n, f"{tr.stop_low_ticks:g}..{tr.stop_high_ticks:g}", "-", outcome.stops.code, "-"))
            continue
        c = result.calibration[n]
        if n in spec.full_turn:  # LeRobot's full-turn convention: range 0..res−1, the homing centres the stops
            mid = 0.5 * (tr.stop_low_ticks + tr.stop_high_ticks)
            present_mid = spec.homing.present(mid, c.homing_offset)
            err = abs((present_mid - (res[n] // 2 - 1) + res[n] / 2) % res[n] - res[n] / 2)
            recovered = f"mid at {present_mid % res[n]:g} (full turn)"
        else:
            lo, hi = stops[n]
            shift = spec.homing.turn_shift(tr.stop_low_ticks, lo, res[n])
            lo, hi = lo + shift, hi + shift
            err = max(abs(lo - tr.stop_low_ticks), abs(hi - tr.stop_high_ticks))
            recovered = f"{lo}..{hi}"
        good = err <= AUTO_ARM_TOLERANCE_TICKS
        ok = ok and good
        rows.append(
            (
                n,
                f"{tr.stop_low_ticks:g}..{tr.stop_high_ticks:g}",
                recovered + ("" if good else " !"),
                f"{err:g}",
                f"{c.homing_offset} / {c.range_min}..{c.range_max}",
            )
        )
    table = TruthTable(
        f"{name}: true vs recovered hard stops (actual ticks)",
        ("joint", "true stops", "recovered", "error ticks", "homing_offset / range"),
        tuple(rows),
    )
    kept = ", ".join(o.name for o in result.auto.not_searched)
    lines = [
        f"{result.auto.total_time_s:.1f} s simulated; wrote {result.path}{temporary_note(temporary)}",
    ]
    if kept:
        lines.insert(0, f"not searched (no hard stop, calibration kept): {kept}")
    code = 0 if ok else 1
    return DemoResult(
        robot, "auto", folder, temporary, code, result, sections=(DemoSection(table),), lines=tuple(lines)
    )
