"""``lerobot calibrate --auto --verify`` accuracy (issue 30 item 2): 20 seeded runs on the physics simulator.

Per seed: a simulated SO-101 follower with physics (its stops drawn by the seed), the stored calibration its true
one (stops from the arm's truth) with a drift of a seeded number of counts (±10..200, 0.9-17.6°) injected into a
seeded joint's homing offset (file and EEPROM alike), then ``verify_calibration``. Prints per run the injected and
estimated drift, the error, the uncertainty, the search time on the arm's clock and the wall time; then the worst
error (target ≤ 0.3°), the other joints' largest |drift| (target ≤ 0.3°), whether the EEPROM and the file stayed
as they were, the longest search (target < 60 s). The baseline measured in the same run: ``lerobot calibrate
--auto`` itself (one full calibration of seed 0), whose time the verify must not exceed by much. The run is
:func:`robocal.workflows.lerobot.verify_sim.verify_drift_run`, the one ``tests/health/test_verify.py`` calls;
``--robot koch_follower`` runs the Koch (Dynamixel) instead.
"""

from __future__ import annotations

import sys
import tempfile
import time
from pathlib import Path
from typing import Any

import numpy as np

from robocal.workflows.lerobot import robot_spec
from robocal.workflows.lerobot.auto import AutoCalibrationRequest, auto_calibrate, auto_section
from robocal.workflows.lerobot.auto_sim import open_auto_arm
from robocal.workflows.lerobot.verify_sim import verify_drift_run

ROBOT = "so101_follower"


def one_run(seed: int, robot: str = ROBOT) -> dict[str, Any]:
    """One seeded verify with an injected drift (:func:`verify_drift_run`, the run the tests call)."""
    section = auto_section(robot)
    rng = np.random.default_rng(seed)
    searched = [j.name for j in section.searched_joints]
    joint = searched[int(rng.integers(0, len(searched)))]
    counts = int(rng.integers(10, 201)) * (1 if rng.random() < 0.5 else -1)
    run = verify_drift_run(robot, seed, joint, counts)
    return {
        "seed": seed,
        "joint": joint,
        "injected": run.injected_deg,
        "estimate": run.estimate_deg,
        "uncertainty": next(j.uncertainty_deg for j in run.result.joints if j.name == joint),
        "others": run.others_deg,
        "search_s": run.result.search_s,
        "wall_s": run.result.wall_s,
        "unchanged": run.unchanged,
    }


def baseline_s(robot: str = ROBOT) -> tuple[float, float]:
    """One full ``lerobot calibrate --auto`` of seed 0: (arm clock s, wall s)."""
    spec, section = robot_spec(robot), auto_section(robot)
    port = "sim?seed=0&transport=inproc"
    with tempfile.TemporaryDirectory() as folder, open_auto_arm(spec, port, section) as arm:
        t0, c0 = time.monotonic(), arm.clock.now()
        request = AutoCalibrationRequest(spec, section, path=Path(folder) / "f.json")
        auto_calibrate(arm.bus, request, clock=arm.clock)
        return arm.clock.now() - c0, time.monotonic() - t0


def main(argv: list[str] | None = None) -> None:
    args = sys.argv[1:] if argv is None else argv
    n = int(args[args.index("--seeds") + 1]) if "--seeds" in args else 20
    robot = args[args.index("--robot") + 1] if "--robot" in args else ROBOT
    base_clock, base_wall = baseline_s(robot)
    print(
        f"{robot} baseline: lerobot calibrate --auto, seed 0: {base_clock:.1f} s on the arm's clock, {base_wall:.1f} s wall"
    )
    print(
        f"{'seed':>4}  {'joint':13s} {'injected °':>10} {'estimate °':>10} {'error °':>8} {'± °':>6}"
        f" {'others °':>8} {'search s':>8} {'wall s':>6}  nothing written"
    )
    runs = []
    for seed in range(n):
        r = one_run(seed, robot)
        runs.append(r)
        err = r["estimate"] - r["injected"]
        print(
            f"{seed:>4}  {r['joint']:13s} {r['injected']:>+10.2f} {r['estimate']:>+10.2f} {err:>+8.2f}"
            f" {r['uncertainty']:>6.2f} {r['others']:>8.2f} {r['search_s']:>8.1f} {r['wall_s']:>6.1f}  {r['unchanged']}"
        )
    worst = max(abs(r["estimate"] - r["injected"]) for r in runs)
    others = max(r["others"] for r in runs)
    longest = max(r["search_s"] for r in runs)
    written = sum(not r["unchanged"] for r in runs)
    print(
        f"worst error {worst:.3f}° (target ≤ 0.3°); other joints ≤ {others:.3f}°; longest search {longest:.1f} s "
        f"(target < 60 s; {longest / base_clock:.2f}x the calibration); runs that wrote something: {written}"
    )
    if worst > 0.3 or others > 0.3 or longest >= 60 or written:
        raise SystemExit("health_verify: below target")


if __name__ == "__main__":
    main()
