"""Sweep pipeline throughput (14 joints, 1 kHz) and runtime read/write tick rate on the virtual CAN bus.

Each measurement is printed beside a baseline measured in the same run:

* sweep pipeline: the live path (one ``RangeTracker.update`` per sample, then bisection and diagnostics) vs a
  plain ``np.minimum``/``np.maximum`` running range (no unwrapping); the headroom over 1 kHz must be ≥ 100×.
* runtime: ``CalibratedRobot.read()`` + ``write()`` per tick vs the same bus polls with no calibration, and the
  share of the tick spent in the calibration math.
"""

from __future__ import annotations

import math
import tempfile
import time
from pathlib import Path

import numpy as np

from robocal.backends.sim.lite import LITE_JOINTS, lite_urdf_text
from robocal.core.sweep import RangeTracker, analyse_sweep
from robocal.workflows.sweep.job import SweepRequest, run_sweep
from robocal.workflows.sweep.robot import open_robot

N = len(LITE_JOINTS)
RATE_HZ = 1000.0


def _signals(seconds: float) -> np.ndarray:
    t = np.arange(int(seconds * RATE_HZ)) / RATE_HZ
    lo = np.array([j.lower for j in LITE_JOINTS])
    up = np.array([j.upper for j in LITE_JOINTS])
    phase = np.linspace(0, 1, N)
    x = 0.5 + 0.5 * np.sin(2 * math.pi * (0.2 * t[:, None] + phase))
    s = lo + (up - lo) * x + 2.5  # offset pushes some joints across the ±π wrap
    wrapped: np.ndarray = (s + math.pi) % (2 * math.pi) - math.pi
    return wrapped


def bench_pipeline(seconds: float = 20.0) -> float:
    data = _signals(seconds)
    rows = list(data)
    names = [j.name for j in LITE_JOINTS]
    d = np.array([j.direction for j in LITE_JOINTS], dtype=float)
    lo = np.array([j.lower for j in LITE_JOINTS])
    up = np.array([j.upper for j in LITE_JOINTS])

    t0 = time.perf_counter()
    mn = np.full(N, np.inf)
    mx = np.full(N, -np.inf)
    for r in rows:
        np.minimum(mn, r, out=mn)
        np.maximum(mx, r, out=mx)
    base = time.perf_counter() - t0

    t0 = time.perf_counter()
    tr = RangeTracker(N)
    for r in rows:
        tr.update(r)
    analyse_sweep(names, d, lo, up, tr.minimum, tr.maximum)
    live = time.perf_counter() - t0

    t0 = time.perf_counter()
    tr2 = RangeTracker(N)
    for i in range(0, len(data), 1000):
        tr2.update_many(data[i : i + 1000])
    block = time.perf_counter() - t0
    assert np.allclose(tr.sweep, tr2.sweep)

    n = len(rows)
    live_rate = n / live
    print(f"sweep pipeline, {N} joints, {n} samples ({seconds:g} s at 1 kHz):")
    print(f"  baseline plain min/max per sample : {n / base:12.0f} samples/s")
    print(
        f"  robocal tracker per sample (live) : {live_rate:12.0f} samples/s  ({base / live:.2f}x baseline speed)"
    )
    print(f"  robocal tracker, 1000-row blocks  : {n / block:12.0f} samples/s")
    print(f"  headroom over 1 kHz (live path)   : {live_rate / RATE_HZ:12.0f}x  (need >= 100x)")
    return live_rate / RATE_HZ


def bench_runtime(ticks: int = 400) -> None:
    with tempfile.TemporaryDirectory() as tmp:
        urdf = Path(tmp) / "lite.urdf"
        urdf.write_text(lite_urdf_text())
        cal_path = Path(tmp) / "cal.yaml"
        run_sweep(SweepRequest(urdf, "sim:lite?seed=5", cal_path))
        with open_robot(urdf, cal_path, "sim:lite?seed=5&noise=0", timeout_s=0.5) as robot:
            src = robot.source
            for _ in range(20):
                src.read()
            state = robot.read()
            q = state.position_rad.copy()
            robot.write(q, 0.0, 0.0, 0.0, 0.0)
            # baseline and robocal alternate in short rounds and each keeps its best round, so load from other
            # processes on the machine (which comes and goes) does not land on one side only
            rounds, per_round = 60, 10
            base = tick = math.inf
            for _ in range(rounds):
                t0 = time.perf_counter()
                for _ in range(per_round):
                    src.read()
                base = min(base, (time.perf_counter() - t0) / per_round)
                t0 = time.perf_counter()
                for _ in range(per_round):
                    robot.read()
                    robot.write(q, 0.0, 0.0, 0.0, 0.0)
                tick = min(tick, (time.perf_counter() - t0) / per_round / 2)  # per bus round (read or write)

            cal = robot.calibration
            raw = np.zeros((3, N))  # rows position, velocity, effort: the fused map CalibratedRobot uses
            t0 = time.perf_counter()
            for _ in range(ticks * 10):
                cal.state_to_joint(raw)
                cal.state_to_raw(raw)
            math_s = (time.perf_counter() - t0) / (ticks * 10) / 2
    print(f"runtime read/write, {N} joints on two virtual CAN buses (best of 60 alternating rounds of 10 ticks):")
    print(f"  baseline raw poll (no calibration): {1 / base:8.0f} ticks/s  ({base * 1e3:.3f} ms)")
    print(f"  CalibratedRobot read or write     : {1 / tick:8.0f} ticks/s  ({tick * 1e3:.3f} ms)")
    print(f"  ratio calibrated / baseline rate  : {base / tick:8.2f}")
    print(
        f"  calibration math per tick         : {math_s * 1e6:8.1f} us = {100 * math_s / tick:.2f} % of the tick"
    )


def main() -> None:
    headroom = bench_pipeline()
    bench_runtime()
    if headroom < 100:
        raise SystemExit(f"sweep pipeline headroom {headroom:.0f}x is below 100x")


if __name__ == "__main__":
    main()
