"""Auto-calibration acceptance over the wire: the whole simulated Lite behind python-can, seeded, in parallel.

``python benchmarks/run.py autocal_wire`` runs ``robocal sweep --auto``'s workflow
(:func:`robocal.workflows.autocal.sweep.run_sweep_auto`) on the simulated Lite of ``--source sim:lite?seed=N``:
14 simulated Robstride motors on two python-can ``virtual`` channels, each motor's firmware (MIT law, torque limit
0x700B, type-2 feedback quantised as on the wire) moving a physics plant on one simulated clock, driven by the
same :class:`~robocal.backends.robstride.RobstrideBus` and joint drivers as real motors. One run is the whole
arm (every joint, one seed); a scenario puts its fault (``soft``, ``missing``, ``obstacle``, ...) on every joint.

``AUTOCAL_WIRE_SEEDS=N`` whole-arm runs per scenario (default 100: 100 runs of every joint), ``AUTOCAL_WIRE_WORKERS``
processes (default 2 × CPUs: a run waits on the bus threads far more than it computes), ``AUTOCAL_WIRE_SCENARIOS=a,b``
a subset. Truth: each simulated motor's true homing offset and its plant's stops; zero error = recovered homing
offset − true one, span error = measured span − the plant's. The table and verdicts are those of
``benchmarks/bench_autocal.py`` (:func:`bench_autocal.acceptance_problems`).
"""

from __future__ import annotations

import math
import os
import sys
import tempfile
import time
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

from bench_autocal import (
    RunResult,
    ScenarioSpec,
    ScenarioStats,
    print_table_header,
    print_table_row,
)

from robocal.backends.sim.physics import Scenario
from robocal.workflows.autocal.job import AutoCalFailedError, AutoCalResult

__all__ = ["WIRE_SCENARIOS", "run_arm", "run_wire_scenario"]

WIRE_SCENARIOS: tuple[tuple[ScenarioSpec, str], ...] = (
    (ScenarioSpec("stiff_600", Scenario()), ""),
    (ScenarioSpec("soft_15", Scenario(soft_stop=True), zero_tol_deg=1.5, span_tol_deg=1.5), "soft"),
    (ScenarioSpec("stiction_0.8", Scenario(stiction_ratio=0.8)), "stiction"),
    (
        ScenarioSpec("overload_latch", Scenario(overload_latch=True), confirmed_by="overload+reread"),
        "overload",
    ),
    (ScenarioSpec("silent_at_stop", Scenario(silent_at_stop=True)), "silent"),
    (ScenarioSpec("missing_stop", Scenario(missing_stop="upper"), expect="abort"), "missing"),
    (ScenarioSpec("obstacle", Scenario(obstacle=True), expect="span_mismatch"), "obstacle"),
    (ScenarioSpec("cable_snag", Scenario(cable_snag=True), expect="span_mismatch"), "snag"),
)
"""Each scenario and the ``sim:lite`` option that puts its fault on every joint ("" for none)."""


def run_arm(fault: str, seed: int) -> list[RunResult]:
    """Auto-calibrate the whole simulated Lite (``sim:lite?seed=seed``, ``fault`` on every joint); one result a joint."""
    from robocal.backends.sim.lite import LITE_JOINTS, lite_urdf_text
    from robocal.workflows.autocal.sim import SimAutoLite, sim_opener
    from robocal.workflows.autocal.sweep import SweepAutoRequest, run_sweep_auto

    names = [j.name for j in LITE_JOINTS]
    span_rad = {j.name: j.upper - j.lower for j in LITE_JOINTS}
    source = f"sim:lite?seed={seed}" + (f"&{fault}={','.join(names)}" if fault else "")
    holder: list[SimAutoLite] = []
    with tempfile.TemporaryDirectory() as tmp:
        urdf = Path(tmp) / "lite.urdf"
        urdf.write_text(lite_urdf_text())
        out = Path(tmp) / "cal.yaml"
        recovered: dict[str, float] = {}
        try:
            outcome = run_sweep_auto(
                SweepAutoRequest(
                    urdf,
                    source,
                    out,
                    robot="bhl_arms",
                ),
                open_drivers_fn=sim_opener(holder),
            )
            auto: AutoCalResult = outcome.auto
            recovered = {j.name: j.homing_offset for j in outcome.result.joints}
        except AutoCalFailedError as e:
            auto = e.result
            if out.exists():
                raise AssertionError(f"seed {seed} {fault}: a failed run wrote {out}") from None
    sim = holder[0]
    truth = sim.true_offsets()
    results = []
    for o in auto.joints:
        motor = sim.motors[o.name]
        res = RunResult.from_outcome(
            o, limp_at_end=motor.mode == 0, peak_tau_nm=motor.plant.peak_tau_motor_nm, cap_nm=o.cap_nm,
            speed_rad_s=o.speed_rad_s, abort_span_rad=span_rad[o.name],
        )  # fmt: skip
        p = motor.plant.params
        if o.ok and o.name in recovered:
            res.zero_err_deg = math.degrees(recovered[o.name] - truth[o.name])
            if p.stop_lower_rad is not None and p.stop_upper_rad is not None:
                res.span_err_deg = math.degrees(o.stops.span_rad - (p.stop_upper_rad - p.stop_lower_rad))
        results.append(res)
    return results


def _run_arm_args(args: tuple[str, int]) -> list[RunResult]:
    return run_arm(*args)


def run_wire_scenario(
    spec: ScenarioSpec, fault: str, seeds: range, pool: ProcessPoolExecutor | None = None
) -> ScenarioStats:
    """Run ``spec`` (``fault`` on every joint) for every seed, whole arm per seed, in ``pool`` when given."""
    st = ScenarioStats("lite-wire", spec)
    jobs = [(fault, s) for s in seeds]
    for runs in pool.map(_run_arm_args, jobs) if pool is not None else map(_run_arm_args, jobs):
        st.runs.extend(runs)
    return st


def main() -> None:
    n = int(os.environ.get("AUTOCAL_WIRE_SEEDS", "100"))
    workers = int(os.environ.get("AUTOCAL_WIRE_WORKERS", str(2 * (os.cpu_count() or 1))))
    wanted = [s for s in os.environ.get("AUTOCAL_WIRE_SCENARIOS", "").split(",") if s]
    failures = 0
    print(
        f"-- lite over the wire (python-can virtual, Robstride firmware sim): {n} whole-arm runs per scenario --"
    )
    print_table_header()
    with ProcessPoolExecutor(max_workers=workers) as pool:
        for spec, fault in WIRE_SCENARIOS:
            if wanted and spec.name not in wanted:
                continue
            t0 = time.perf_counter()
            failures += print_table_row(run_wire_scenario(spec, fault, range(n), pool))
            print(f"{'':18s} ({time.perf_counter() - t0:.0f} s wall, {workers} processes)", flush=True)
    print(f"autocal over the wire: {'PASS' if not failures else f'{failures} FAIL'}")


if __name__ == "__main__":
    main()
