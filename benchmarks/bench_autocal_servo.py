"""Auto-calibration acceptance of the LeRobot arms on the servo firmware simulation, behind the real vendor SDK.

``python benchmarks/run.py autocal-servo`` runs, per scenario and per joint of the SO-101 follower, seeded
single-joint runs of ``robocal lerobot calibrate --auto``'s workflow (:func:`robocal.workflows.lerobot.auto.
auto_calibrate`): the unmodified Feetech SDK (scservo_sdk, through robocal's FeetechBus) talks over a
pseudo-terminal to simulated STS3215 servos whose firmware (:mod:`robocal.backends.sim.servo_firmware`: position
servo with ``Torque_Limit``, ``Present_Load``, the overload ``Status`` bit and its protection time) moves a joint
plant (:mod:`robocal.backends.sim.physics`) on a simulated clock. ``AUTOCAL_SEEDS=N`` seeds per scenario and
joint (default 100: 7 200 runs, hours of wall time on this machine), ``AUTOCAL_SCENARIOS=a,b`` a subset of the
scenarios; ``AUTOCAL_ROBOT=koch_follower`` runs the
Koch (Dynamixel firmware) instead. The test suite (tests/autocal/test_acceptance_servo.py) runs 2 seeds of every
scenario (seed → joint, cycling) through the same :func:`run_one` and thresholds.

Truth: the plant's own stops (after the scenario moved them) in the servo's actual ticks; the found contact
surfaces are the searches' ``q_stop`` (driver frame: Present ticks at ``Homing_Offset`` 0). Zero error = the
mean of the two stop errors (the midpoint rule's error), span error = their difference.
"""

from __future__ import annotations

import math
import os
import sys
from collections.abc import Sequence
from dataclasses import replace
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

from bench_autocal import (
    SCENARIOS,
    THRESHOLDS,
    RunResult,
    ScenarioSpec,
    ScenarioStats,
    print_table_header,
    print_table_row,
)

from robocal.backends.servo_ratings import RATINGS
from robocal.backends.sim.arm_physics import ARM_NOMINAL, attach_physics
from robocal.backends.sim.lerobot_arms import JointTruth, SimArm, seeded_truth
from robocal.backends.sim.physics import SimClock
from robocal.workflows.autocal import AutoCalFailedError, AutoCalResult
from robocal.workflows.lerobot import robot_spec
from robocal.workflows.lerobot.arms import open_bus
from robocal.workflows.lerobot.auto import auto_calibrate, auto_section

__all__ = ["SERVO_SCENARIOS", "arm_total_time", "run_one", "run_scenario"]

SERVO_SCENARIOS: tuple[ScenarioSpec, ...] = SCENARIOS
"""The scenarios and per-scenario tolerances of the Lite/MIT benchmark (benchmarks/bench_autocal.py)."""


def cad_truth(robot: str, seed: int) -> dict[str, JointTruth]:
    """The simulated arm's truth with each searched joint's stops at the profile's expected (CAD) angles.

    The seed places each joint's mid pose (the unknown zero, :func:`seeded_truth`); the stops sit at the
    profile's ``lower_deg``/``upper_deg`` from it, as the Lite benchmark puts them at the URDF limits (the
    ``asymmetric`` scenario moves each by up to ±5°).
    """
    truth = seeded_truth(robot, seed)
    for j in auto_section(robot).searched_joints:
        t = truth[j.name]
        lo, hi = j.expected_rad(None, None)
        assert lo is not None and hi is not None
        per_rad = 4096 / (2 * math.pi)
        truth[j.name] = JointTruth(t.mid_ticks, t.mid_ticks + lo * per_rad, t.mid_ticks + hi * per_rad)
    return truth


def _wrap(d_ticks: float, res: int) -> float:
    return (d_ticks + res / 2) % res - res / 2


def run_one(robot: str, spec: ScenarioSpec, seed: int, joint: str | None = None) -> RunResult:
    """Auto-calibrate one joint (``joint``, default the ``seed``-th of the profile's order) in scenario ``spec``."""
    arm_spec = robot_spec(robot)
    section = auto_section(robot)
    order = [j.name for j in section.searched_joints]
    name = joint or order[seed % len(order)]
    aj = section.joint(name)
    assert aj is not None
    model = arm_spec.motors[arm_spec.motor_names.index(name)].model
    stall = RATINGS[model].stall_torque_nm
    cap = aj.torque_fraction * stall  # Torque_Limit / Goal_Current of the fraction of the full torque
    scen = spec.plant_scenario(cap)
    nominal = replace(ARM_NOMINAL, stiffness_lower=spec.stiffness, stiffness_upper=spec.stiffness)
    clock = SimClock()
    with SimArm(arm_spec, truth=cad_truth(robot, seed)) as arm:
        plants = attach_physics(
            arm, clock, scenarios={name: scen}, search_torque_nm=cap, nominal=nominal, seed=seed
        )
        bus = open_bus(arm_spec, arm.port)
        try:
            auto: AutoCalResult
            try:
                auto = auto_calibrate(bus, arm_spec, section, clock=clock, joints=[name]).auto
            except AutoCalFailedError as exc:
                auto = exc.result
            servo = arm.servo(name)
            limp = not servo.get_reg("Torque_Enable")
        finally:
            bus.close()
        plant = plants[name]
        truth = arm.truth[name]
        res = servo.resolution
    out = auto[name]
    run = RunResult(name, out.stops.code, time_s=out.time_s, limp_at_end=limp)
    run.peak_over_cap = plant.peak_tau_motor_nm / cap
    lo, hi = out.stops.lower, out.stops.upper
    run.tests = tuple(r.test for r in (lo, hi) if r is not None and r.ok)
    p = plant.params
    if (
        out.ok
        and lo is not None
        and hi is not None
        and p.stop_lower_rad is not None
        and p.stop_upper_rad is not None
    ):
        per_rad = res / (2 * math.pi)
        true_lo = truth.mid_ticks + p.stop_lower_rad * per_rad
        true_hi = truth.mid_ticks + p.stop_upper_rad * per_rad
        e_lo = _wrap(lo.q_stop_rad * per_rad - true_lo, res)
        e_hi = _wrap(hi.q_stop_rad * per_rad - true_hi, res)
        run.zero_err_deg = 0.5 * (e_lo + e_hi) * 360.0 / res
        run.span_err_deg = (e_hi - e_lo) * 360.0 / res
    failed = [r for r in (lo, hi) if r is not None and not r.ok]
    if failed:
        exp_lo, exp_hi = aj.expected_rad(None, None)
        span = (exp_hi or 0.0) - (exp_lo or 0.0)
        run.abort_time_s = failed[0].duration_s
        run.abort_bound_s = (span + math.radians(aj.tolerance_deg)) / aj.speed_rad_s
    return run


def run_scenario(
    robot: str, spec: ScenarioSpec, seeds: Sequence[int], *, per_joint: bool = False
) -> ScenarioStats:
    """``spec`` for every seed: one joint per seed (cycling), or every joint per seed with ``per_joint``."""
    st = ScenarioStats(robot, spec)
    joints = [j.name for j in auto_section(robot).searched_joints]
    for seed in seeds:
        if per_joint:
            st.runs += [run_one(robot, spec, seed, j) for j in joints]
        else:
            st.runs.append(run_one(robot, spec, seed))
    return st


def arm_total_time(robot: str, seed: int = 0) -> float:
    """Simulated time of a whole clean arm auto-calibrated in one run (every joint, transit and parking)."""
    arm_spec = robot_spec(robot)
    section = auto_section(robot)
    clock = SimClock()
    with SimArm(arm_spec, truth=cad_truth(robot, seed)) as arm:
        push = {
            j.name: j.torque_fraction * RATINGS[m.model].stall_torque_nm
            for m in arm_spec.motors
            if (j := section.joint(m.name)) is not None
        }
        attach_physics(arm, clock, search_torque_nm=push, seed=seed)
        bus = open_bus(arm_spec, arm.port)
        try:
            auto = auto_calibrate(bus, arm_spec, section, clock=clock).auto
        finally:
            bus.close()
    assert not auto.failed, auto.failure_summary()
    return auto.total_time_s


def main() -> None:
    n = int(os.environ.get("AUTOCAL_SEEDS", "100"))
    robot = os.environ.get("AUTOCAL_ROBOT", "so101_follower")
    limit = THRESHOLDS["so101_total_s"]
    print(f"-- {robot} on the servo firmware simulation (real SDK, pty): {n} seeds per scenario per joint --")
    print_table_header()
    failures = 0
    wanted = [w for w in os.environ.get("AUTOCAL_SCENARIOS", "").split(",") if w]
    for spec in SERVO_SCENARIOS:
        if wanted and spec.name not in wanted:
            continue
        failures += print_table_row(run_scenario(robot, spec, range(n), per_joint=True))
    total = arm_total_time(robot)
    print(
        f"whole {robot}: {total:.1f} s simulated (limit {limit:.0f} s) {'PASS' if total < limit else 'FAIL'}"
    )
    failures += total >= limit
    print(f"autocal-servo acceptance: {'PASS' if not failures else f'{failures} FAIL'}")
