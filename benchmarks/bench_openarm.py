"""Zero-touch calibration of the simulated OpenArm v10 over python-can: 20 seeded whole-arm runs (issue 31).

``python benchmarks/run.py openarm`` runs ``robocal sweep --auto``'s workflow
(:func:`robocal.workflows.autocal.sweep.run_sweep_auto`) on ``--source sim:openarm?seed=N`` with the shipped
``openarm_follower_<side>`` profile: eight simulated Damiao motors (MIT law, TIMEOUT, state codes, frames scaled by
PMAX / VMAX / TMAX) behind their joint plants (assumed gravity, friction, backlash, metal and printed stops) on one
simulated clock, driven by the same :class:`~robocal.backends.damiao.bus.DamiaoBus` and
:class:`~robocal.backends.damiao.joint_driver.DamiaoJointDriver` as a real arm.

Truth: ``SimOpenArm.zero_error_rad`` (the offset a perfect calibration finds) and each plant's stops. Per joint over
the seeds: the zero error's mean (bias) and standard deviation (repeatability), and the largest measured-range
error. Baseline in the same run: LeRobot 0.6.1's own procedure on the same arm ("arm hanging straight down,
gripper closed", ``set_zero_position()``, range −90…90 for every joint): its zero error is where the simulated
person's hanging pose leaves each joint, its range error |180° − the true range|.

Done when (issue 31): σ ≤ 0.05°, |bias| ≤ 0.2°, every range within 0.5° of the simulated stops.
``OPENARM_SEEDS=N`` (default 20), ``OPENARM_SIDE=left`` (default right), ``OPENARM_WORKERS`` (default 2).
"""

from __future__ import annotations

import math
import os
import tempfile
import time
from concurrent.futures import ProcessPoolExecutor
from importlib import resources
from pathlib import Path

import numpy as np

__all__ = ["main", "run_seed"]


def run_seed(side: str, seed: int) -> dict[str, tuple[float, float, float]]:
    """One whole-arm run: URDF joint → (zero error °, range error °, simulated seconds of the run)."""
    from robocal.workflows.autocal.damiao import SimAutoOpenArm, sim_openarm_opener
    from robocal.workflows.autocal.sweep import SweepAutoRequest, run_sweep_auto

    urdf = Path(str(resources.files("robocal").joinpath("data", f"openarm_v10_{side}.urdf")))
    holder: list[SimAutoOpenArm] = []
    with tempfile.TemporaryDirectory() as folder:
        try:
            outcome = run_sweep_auto(
                SweepAutoRequest(urdf, f"sim:openarm?seed={seed}", Path(folder) / "c.yaml", robot=f"openarm_follower_{side}"),
                open_drivers_fn=sim_openarm_opener(holder),
            )
        finally:
            for sim in holder:
                sim.close()
    sim = holder[0]
    out: dict[str, tuple[float, float, float]] = {}
    for o in outcome.auto.joints:
        truth = next(j for j in sim.arm.joints if j.name == sim.names[o.name])
        span = math.degrees(truth.stop_upper_rad - truth.stop_lower_rad)
        zero = math.degrees(o.stops.offset_rad - sim.arm.zero_error_rad(truth.name))
        out[o.name] = (zero, math.degrees(o.stops.span_rad) - span, outcome.auto.total_time_s)
    return out


def main() -> None:
    """Run the seeds, print the table and the verdict.

    Raises:
        SystemExit: A done-when bound is missed (``run.py`` reports the benchmark failed).
    """
    from robocal.backends.damiao.openarm import openarm_joints

    seeds = int(os.environ.get("OPENARM_SEEDS", "20"))
    side = os.environ.get("OPENARM_SIDE", "right")
    workers = int(os.environ.get("OPENARM_WORKERS", "2"))
    t0 = time.perf_counter()
    with ProcessPoolExecutor(workers) as pool:
        runs = list(pool.map(run_seed, [side] * seeds, range(seeds)))
    wall = time.perf_counter() - t0
    names = list(runs[0])
    print(f"simulated OpenArm v10 ({side} arm), {seeds} seeded whole-arm runs of sweep --auto, {wall:.0f} s wall "
          f"({workers} workers), {np.mean([next(iter(r.values()))[2] for r in runs]):.0f} s simulated per arm")
    print(f"{'joint':30s} {'bias °':>8s} {'σ °':>7s} {'max |zero| °':>13s} {'max |range err| °':>18s}"
          f" | LeRobot ±90: zero °, range err °")
    truth = {j.name: j for j in openarm_joints(side)}  # type: ignore[arg-type]
    bad: list[str] = []
    for name in names:
        zeros = np.array([r[name][0] for r in runs])
        spans = np.array([r[name][1] for r in runs])
        lerobot = name.rsplit("_", 1)[-1]
        t = truth["gripper" if name.endswith("gripper_motor") else f"joint_{lerobot[-1]}"]
        lr_zero = math.degrees(t.rest_rad)
        lr_span = abs(180.0 - math.degrees(t.stop_upper_rad - t.stop_lower_rad))
        bias, sigma = float(zeros.mean()), float(zeros.std(ddof=1)) if seeds > 1 else 0.0
        print(f"{name:30s} {bias:+8.4f} {sigma:7.4f} {np.abs(zeros).max():13.4f} {np.abs(spans).max():18.4f}"
              f" | {lr_zero:+6.2f} {lr_span:8.1f}")
        if sigma > 0.05 or abs(bias) > 0.2 or np.abs(spans).max() > 0.5:
            bad.append(name)
    print("done-when (σ ≤ 0.05°, |bias| ≤ 0.2°, range within 0.5°):", "met" if not bad else f"MISSED by {bad}")
    if bad:
        raise SystemExit(f"done-when missed by {', '.join(bad)}")


if __name__ == "__main__":
    main()
