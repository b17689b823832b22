"""Auto-calibration acceptance of the LeRobot arms on the servo firmware simulation, behind the real vendor SDK.

``python benchmarks/run.py autocal_servo`` runs, per scenario and per joint of the SO-101 follower, seeded
single-joint runs of ``robocal lerobot calibrate --auto``'s workflow (:func:`robocal.workflows.lerobot.auto.
auto_calibrate`): the unmodified Feetech SDK (scservo_sdk, through robocal's FeetechBus) talks to simulated
STS3215 servos whose firmware (:mod:`robocal.backends.sim.servo_firmware`: position servo with ``Torque_Limit``,
``Present_Load``, the overload ``Status`` bit and its protection time) moves a joint plant
(:mod:`robocal.backends.sim.physics`) on a simulated clock. The SDK's serial port is an in-process port
(``SimArm(transport="inproc")``: the SDK's bytes go straight to the simulator's packet parser, the same packets
as over the pseudo-terminal, without the pty and its busy polling); ``AUTOCAL_TRANSPORT=pty`` runs over a
pseudo-terminal instead.

Seeds: ``AUTOCAL_SEEDS_PER_JOINT=N`` runs every searched joint N times per scenario (seeds 0…N−1, each joint
alone); ``AUTOCAL_SEEDS=N`` N runs per scenario, seed → joint cycling (as ``bench_autocal``); neither: 100 per
joint, the issue's acceptance (7 200 runs per arm). ``AUTOCAL_SCENARIOS=a,b`` a subset of the scenarios;
``AUTOCAL_ROBOTS=so101_follower,koch_follower`` (or ``AUTOCAL_ROBOT``) the arms (default the SO-101; the Koch
runs on the Dynamixel firmware); ``AUTOCAL_WORKERS=N`` worker processes (default: one per core; each run is
seeded and independent, so the table is the same with any number). The test suite (tests/autocal/test_acceptance_servo.py) runs 2 seeds of every
scenario (seed → joint, cycling) through the same :func:`run_one` and thresholds.

Truth: the plant's own stops (after the scenario moved them) in the servo's actual ticks; the found contact
surfaces are the searches' ``q_stop`` (driver frame: Present ticks at ``Homing_Offset`` 0). Zero error = the
mean of the two stop errors (the midpoint rule's error), span error = their difference.
"""

from __future__ import annotations

import math
import os
import sys
import time
from collections.abc import Sequence
from concurrent.futures import ProcessPoolExecutor
from dataclasses import replace
from pathlib import Path

import numpy as np

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
from robocal.workflows.autocal.job import AutoCalFailedError, AutoCalResult
from robocal.workflows.lerobot import robot_spec
from robocal.workflows.lerobot.arms import open_bus
from robocal.workflows.lerobot.auto import AutoCalibrationRequest, auto_calibrate, auto_section

__all__ = ["SERVO_SCENARIOS", "arm_total_time", "run_one", "run_scenario"]

SERVO_SCENARIOS: tuple[ScenarioSpec, ...] = SCENARIOS
"""The scenarios and per-scenario tolerances of the Lite/MIT benchmark (benchmarks/bench_autocal.py)."""


def cad_truth(robot: str, seed: int) -> dict[str, JointTruth]:
    """The simulated arm's truth with each searched joint's stops at the profile's expected (CAD) angles.

    The seed places each joint's mid pose (the unknown zero, :func:`seeded_truth`: whole ticks), moved by a
    seeded fraction of a tick, so the stops fall differently on the encoder's grid from seed to seed (with whole
    ticks only, a scenario without random draws would run the same search up to a translation for every seed);
    the stops sit at the profile's ``lower_deg``/``upper_deg`` from it, as the Lite benchmark puts them at the
    URDF limits (the ``asymmetric`` scenario moves each by up to ±5°).
    """
    truth = seeded_truth(robot, seed)
    rng = np.random.default_rng(20_000 + seed)
    for j in auto_section(robot).searched_joints:
        t = truth[j.name]
        lo, hi = j.expected_rad(None, None)
        assert lo is not None and hi is not None
        per_rad = 4096 / (2 * math.pi)
        mid = t.mid_ticks + float(rng.uniform(0.0, 1.0))
        truth[j.name] = JointTruth(mid, mid + lo * per_rad, mid + hi * per_rad)
    return truth


def start_ticks(truth: JointTruth, seed: int) -> float:
    """Where a searched joint starts (actual ticks): seeded, within ±15 % of its span around the middle."""
    frac = float(np.random.default_rng(40_000 + seed).uniform(-0.15, 0.15))
    middle = 0.5 * (truth.stop_low_ticks + truth.stop_high_ticks)
    return middle + frac * (truth.stop_high_ticks - truth.stop_low_ticks)


def _wrap(d_ticks: float, res: int) -> float:
    return (d_ticks + res / 2) % res - res / 2


def run_one(
    robot: str,
    spec: ScenarioSpec,
    seed: int,
    joint: str | None = None,
    *,
    transport: str = "inproc",
    packet_log: list[tuple[str, bytes]] | None = None,
    packet_timeout_ms: float = 100.0,
) -> RunResult:
    """Auto-calibrate one joint (``joint``, default the ``seed``-th of the profile's order) in scenario ``spec``.

    ``transport``: the simulated arm's port, ``"inproc"`` (default, fast) or ``"pty"`` (a pseudo-terminal);
    the same packets either way. ``packet_log``: a list to record every instruction and status packet in.
    ``packet_timeout_ms``: the SDK's reply timeout (wall time on the pty: a loaded machine that answers later
    makes the SDK retry, one more packet and so a different run; the in-process port does not depend on it).
    """
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
    with SimArm(arm_spec, truth=cad_truth(robot, seed), transport=transport) as arm:
        arm.bus.packet_log = packet_log
        arm.move({name: start_ticks(arm.truth[name], seed)})
        plants = attach_physics(
            arm, clock, scenarios={name: scen}, search_torque_nm=cap, nominal=nominal, seed=seed
        )
        bus = open_bus(arm_spec, arm.port, packet_timeout_ms=packet_timeout_ms)
        try:
            auto: AutoCalResult
            try:
                auto = auto_calibrate(
                    bus,
                    AutoCalibrationRequest(
                        arm_spec,
                        section,
                        joints=[name],
                    ),
                    clock=clock,
                ).auto
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
    exp_lo, exp_hi = aj.expected_rad(None, None)
    run = RunResult.from_outcome(
        out, limp_at_end=limp, peak_tau_nm=plant.peak_tau_motor_nm, cap_nm=cap, speed_rad_s=aj.speed_rad_s,
        abort_span_rad=(exp_hi or 0.0) - (exp_lo or 0.0), tolerance_deg=aj.tolerance_deg,
    )  # fmt: skip
    lo, hi = out.stops.lower, out.stops.upper
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
    return run


def _run_one_args(args: tuple[str, str, int, str | None, str]) -> RunResult:
    robot, scenario, seed, joint, transport = args
    spec = next(s for s in SERVO_SCENARIOS if s.name == scenario)
    return run_one(robot, spec, seed, joint, transport=transport)


def run_scenario(
    robot: str,
    spec: ScenarioSpec,
    seeds: Sequence[int],
    *,
    per_joint: bool = False,
    transport: str = "inproc",
    pool: ProcessPoolExecutor | None = None,
) -> ScenarioStats:
    """``spec`` for every seed: one joint per seed (cycling), or every joint per seed with ``per_joint``.

    ``pool``: run the seeds in these worker processes (each run is independent and seeded, so the results are
    the same as in one process, in the same order).
    """
    st = ScenarioStats(robot, spec)
    joints: list[str | None] = [j.name for j in auto_section(robot).searched_joints] if per_joint else [None]
    tasks = [(robot, spec.name, seed, j, transport) for seed in seeds for j in joints]
    if pool is None:
        st.runs += [_run_one_args(t) for t in tasks]
    else:
        st.runs += list(pool.map(_run_one_args, tasks, chunksize=4))
    return st


def arm_total_time(robot: str, seed: int = 0, *, transport: str = "inproc") -> float:
    """Simulated time of a whole clean arm auto-calibrated in one run (every joint, transit and parking)."""
    arm_spec = robot_spec(robot)
    section = auto_section(robot)
    clock = SimClock()
    with SimArm(arm_spec, truth=cad_truth(robot, seed), transport=transport) as arm:
        push = {
            j.name: j.torque_fraction * RATINGS[m.model].stall_torque_nm
            for m in arm_spec.motors
            if (j := section.joint(m.name)) is not None
        }
        attach_physics(arm, clock, search_torque_nm=push, seed=seed)
        bus = open_bus(arm_spec, arm.port)
        try:
            auto = auto_calibrate(bus, AutoCalibrationRequest(arm_spec, section), clock=clock).auto
        finally:
            bus.close()
    assert not auto.failed, auto.failure_summary()
    return auto.total_time_s


def transport_wall_times(robot: str, repeats: int = 3) -> dict[str, float]:
    """Best wall time (s) of one clean single-joint search (seed 0, the profile's first joint) per transport."""
    spec = SERVO_SCENARIOS[0]
    best = {"pty": math.inf, "inproc": math.inf}
    for _ in range(repeats):
        for transport in best:
            t0 = time.perf_counter()
            run_one(robot, spec, 0, transport=transport)
            best[transport] = min(best[transport], time.perf_counter() - t0)
    return best


def servo_seeds() -> tuple[range, bool, str]:
    """The seeds per scenario, whether each runs every joint, and how they were chosen (for the title).

    ``AUTOCAL_SEEDS_PER_JOINT=N``: N seeds, each run on every searched joint; ``AUTOCAL_SEEDS=N``: N seeds,
    seed → joint cycling; neither: 100 per joint (the issue's acceptance).
    """
    per_joint = os.environ.get("AUTOCAL_SEEDS_PER_JOINT")
    cycling = os.environ.get("AUTOCAL_SEEDS")
    if cycling and not per_joint:
        n = int(cycling)
        return range(n), False, f"{n} seeded runs per scenario (seed → joint, cycling)"
    n = int(per_joint or "100")
    return range(n), True, f"{n} seeded runs per joint and scenario"


def main() -> None:
    robots = [
        r for r in os.environ.get("AUTOCAL_ROBOTS", os.environ.get("AUTOCAL_ROBOT", "")).split(",") if r
    ]
    transport = os.environ.get("AUTOCAL_TRANSPORT", "inproc")
    wanted = [w for w in os.environ.get("AUTOCAL_SCENARIOS", "").split(",") if w]
    seeds, per_joint, how = servo_seeds()
    workers = int(os.environ.get("AUTOCAL_WORKERS", str(os.cpu_count() or 1)))
    failures = 0
    with ProcessPoolExecutor(max_workers=workers) as pool:
        for robot in robots or ["so101_follower"]:
            failures += _bench_robot(robot, transport, wanted, seeds, per_joint, how, pool)
    print(f"autocal-servo acceptance: {'PASS' if not failures else f'{failures} FAIL'}")


def _bench_robot(
    robot: str,
    transport: str,
    wanted: list[str],
    seeds: range,
    per_joint: bool,
    how: str,
    pool: ProcessPoolExecutor,
) -> int:
    """One arm's table (every wanted scenario) and its whole-arm time; the number of failed rows."""
    limit = THRESHOLDS["so101_total_s"]
    failures = 0
    walls = transport_wall_times(robot)
    print(
        f"{robot}: one clean single-joint search {walls['pty']:.2f} s wall over a pty, "
        f"{walls['inproc']:.2f} s in process ({walls['pty'] / walls['inproc']:.1f}× faster; best of 3)"
    )
    joints = len(auto_section(robot).searched_joints)
    print(
        f"-- {robot} on the servo firmware simulation (real SDK, {transport} port): {how} ({joints} joints) --"
    )
    print_table_header(wall=True)
    for spec in SERVO_SCENARIOS:
        if wanted and spec.name not in wanted:
            continue
        t0 = time.perf_counter()
        stats = run_scenario(robot, spec, seeds, per_joint=per_joint, transport=transport, pool=pool)
        failures += print_table_row(stats, time.perf_counter() - t0)
    total = arm_total_time(robot, transport=transport)
    print(
        f"whole {robot}: {total:.1f} s simulated (limit {limit:.0f} s) {'PASS' if total < limit else 'FAIL'}\n",
        flush=True,
    )
    failures += total >= limit
    return failures
