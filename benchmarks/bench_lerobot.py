"""LeRobot normalisation and simulated-bus throughput, each beside a baseline measured in the same run.

* normalise / unnormalise a (100 000, 6) recording with ``robocal.lerobot`` (numpy, one call) vs a transcription
  of LeRobot 0.6.1's per-motor Python loop (``_normalize`` / ``_unnormalize``) on the same data;
* one SYNC_READ of 6 Present_Position registers vs 6 single READs, through the unmodified vendor SDKs and the
  pseudo-terminal simulator (Feetech and Dynamixel);
* a whole simulated SO-101 calibration (mid pose, 25-reading sweep, EEPROM writes, JSON file).

Targets for the normalisation (issue 27): at least fc3533f's speed, ≥ 17× (normalize) and ≥ 28× (unnormalize)
LeRobot's loop in the same run. Measured 2026-11-28 on the shared 2-core machine (load average 11–13), three
alternating runs per version: fc3533f 8–24× / 23–41×; main before the column-group kernels (two runs) 11–16× /
10–14×; now 31–38× / 44–56× (1.0–1.3 M / 1.2–1.4 M rows/s); the table is in docs/lerobot.md.
"""

from __future__ import annotations

import tempfile
import time
from pathlib import Path

import numpy as np
from _timing import best_time

from robocal.backends.sim.lerobot_arms import SimArm, SimArmOperator
from robocal.lerobot import MotorCalibration, normalize, unnormalize
from robocal.workflows.lerobot import CalibrateRequest, calibrate, open_bus, robot_spec

CALS = [MotorCalibration(i + 1, i % 2, 0, 900 + 20 * i, 3000 + 30 * i) for i in range(6)]
MODES = ["degrees"] * 5 + ["range_0_100"]


def _lerobot_loop_normalize(raw: np.ndarray) -> list[list[float]]:
    out = []
    for row in raw.tolist():
        vals = []
        for val, c, mode in zip(row, CALS, MODES, strict=True):
            lo, hi = c.range_min, c.range_max
            if mode == "range_0_100":
                b = min(hi, max(lo, val))
                n = ((b - lo) / (hi - lo)) * 100
                vals.append(100 - n if c.drive_mode else n)
            else:
                vals.append((val - (lo + hi) / 2) * 360 / 4095)
        out.append(vals)
    return out


def _lerobot_loop_unnormalize(values: np.ndarray) -> list[list[int]]:
    out = []
    for row in values.tolist():
        vals = []
        for val, c, mode in zip(row, CALS, MODES, strict=True):
            lo, hi = c.range_min, c.range_max
            if mode == "range_0_100":
                v = 100 - val if c.drive_mode else val
                vals.append(int((min(100.0, max(0.0, v)) / 100) * (hi - lo) + lo))
            else:
                vals.append(int((val * 4095 / 360) + (lo + hi) / 2))
        out.append(vals)
    return out


def _row(what: str, ours: float, base: float, unit: str, n: int) -> None:
    print(
        f"{what:<64} robocal {n / ours:>12,.0f} {unit}   baseline {n / base:>12,.0f} {unit}   ratio {base / ours:6.1f}x"
    )


def bench_normalize() -> None:
    rng = np.random.default_rng(0)
    t = 100_000
    raw = rng.integers(0, 4096, size=(t, 6))
    ours = best_time(lambda: normalize(raw, CALS, MODES))
    base = best_time(lambda: _lerobot_loop_normalize(raw), repeat=1)
    assert np.array_equal(normalize(raw, CALS, MODES), np.array(_lerobot_loop_normalize(raw)))
    _row("normalize (100k x 6) vs LeRobot per-motor loop [target >= 17x]", ours, base, "rows/s", t)
    vals = normalize(raw, CALS, MODES)
    ours = best_time(lambda: unnormalize(vals, CALS, MODES))
    base = best_time(lambda: _lerobot_loop_unnormalize(vals), repeat=1)
    assert unnormalize(vals, CALS, MODES).tolist() == _lerobot_loop_unnormalize(vals)
    _row("unnormalize (100k x 6) vs LeRobot per-motor loop [target >= 28x]", ours, base, "rows/s", t)
    ours = best_time(
        lambda: unnormalize(normalize(raw, CALS, MODES, compat="exact"), CALS, MODES, compat="exact")
    )
    base = best_time(lambda: unnormalize(normalize(raw, CALS, MODES), CALS, MODES))
    _row("exact round trip vs lerobot-compat round trip", ours, base, "rows/s", t)


def bench_bus() -> None:
    n = 200
    for robot in ("so101_follower", "koch_follower"):
        with SimArm(robot_spec(robot)) as arm:
            bus = open_bus(arm.spec, arm.port)
            ids = [m.motor_id for m in arm.spec.motors]
            try:
                ours = best_time(
                    lambda b=bus, i=ids: [b.sync_read("Present_Position", i) for _ in range(n)], repeat=2
                )
                base = best_time(
                    lambda b=bus, i=ids: [[b.read("Present_Position", k) for k in i] for _ in range(n)],
                    repeat=2,
                )
            finally:
                bus.close()
        _row(f"{arm.spec.vendor}: sync read of 6 vs 6 single reads (pty)", ours, base, "reads/s", n)


def bench_calibration() -> None:
    times = []
    with tempfile.TemporaryDirectory() as tmp:
        for k in range(3):
            with SimArm(robot_spec("so101_follower")) as arm:
                bus = open_bus(arm.spec, arm.port)
                try:
                    t0 = time.perf_counter()
                    calibrate(bus, CalibrateRequest(arm.spec, path=Path(tmp) / f"{k}.json"), SimArmOperator(arm))
                    times.append(time.perf_counter() - t0)
                finally:
                    bus.close()
        # baseline: the same number of bus transactions as plain single reads
        with SimArm(robot_spec("so101_follower")) as arm:
            bus = open_bus(arm.spec, arm.port)
            try:
                t0 = time.perf_counter()
                for _ in range(30):
                    for m in arm.spec.motors:
                        bus.read("Present_Position", m.motor_id)
                base = time.perf_counter() - t0
            finally:
                bus.close()
    print(
        f"{'simulated SO-101 calibration (whole procedure)':<48} robocal {min(times) * 1e3:10.1f} ms   "
        f"baseline (180 single reads) {base * 1e3:8.1f} ms   ratio {min(times) / base:6.2f}"
    )


def main() -> None:
    """Run every LeRobot benchmark and print robocal beside its baseline."""
    bench_normalize()
    bench_bus()
    bench_calibration()


if __name__ == "__main__":
    main()
