"""Replay memory and time vs recording length: a CSV of 10^4 … 10^6 rows (14 joints) through ``run_sweep``.

Each length runs in a fresh child process that reports its peak resident memory (``VmHWM``, what the
operating system gave it) and the wall time of the whole sweep. Printed: the peak over a child that
only imports robocal (so only the replay's own memory counts), and the log-log slopes between lengths: memory
must stay flat (slope ≈ 0, the replay is streamed in blocks) and time linear (slope ≈ 1). The baseline, measured
in the same run, is reading the whole file into memory (``read_recording``, what the sweep did before streaming).

``python benchmarks/bench_replay.py [MAX_ROWS]`` (default 10^6; the 10^6-row file is about 180 MB, written to a
temporary folder). ``tests/sweep/test_sweep_replay_stream.py`` checks the bound with ``tracemalloc`` on small
files.
"""

from __future__ import annotations

import itertools
import math
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from robocal.backends.sim.lite import LITE_JOINTS, lite_urdf_text

NAMES = [j.name for j in LITE_JOINTS]


def write_csv(path: Path, rows: int, chunk: int = 100_000) -> None:
    """A full sweep of every joint (identity frame, offset 0.3·direction), ``rows`` rows at 1 kHz."""
    lo = np.array([j.lower for j in LITE_JOINTS])
    up = np.array([j.upper for j in LITE_JOINTS])
    d = np.array([j.direction for j in LITE_JOINTS])
    with open(path, "w") as fh:
        fh.write("t," + ",".join(NAMES) + "\n")
        for start in range(0, rows, chunk):
            k = np.arange(start, min(rows, start + chunk))
            x = 0.5 - 0.5 * np.cos(2 * math.pi * k / max(rows - 1, 1))[:, None]  # lower → upper → lower
            pos = 0.3 * d + lo + (up - lo) * x
            np.savetxt(fh, np.column_stack([k / 1000.0, pos]), fmt="%.9g", delimiter=",")


def child(mode: str, csv: str, urdf: str, out: str) -> None:
    """Run one measurement and print ``peak_MiB seconds``."""
    from robocal.backends.replay import read_recording
    from robocal.workflows.sweep.job import SweepRequest, run_sweep

    t0 = time.perf_counter()
    if mode == "sweep":
        run_sweep(SweepRequest(urdf, f"replay:{csv}", out))
    elif mode == "whole":
        read_recording(Path(csv), NAMES)
    dt = time.perf_counter() - t0
    print(peak_rss_mib(), dt)


def peak_rss_mib() -> float:
    """This process's peak resident memory, MiB: ``VmHWM`` (Linux; unlike ``ru_maxrss`` it is not inherited
    from the parent across ``exec``), else ``ru_maxrss``."""
    try:
        with open("/proc/self/status") as fh:
            for line in fh:
                if line.startswith("VmHWM:"):
                    return int(line.split()[1]) / 1024
    except OSError:
        pass
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024


def run_child(*args: str) -> tuple[float, float]:
    out = subprocess.run(
        [sys.executable, __file__, "--child", *args], capture_output=True, text=True, check=True
    ).stdout.split()
    return float(out[0]), float(out[1])


def slope(x0: float, y0: float, x1: float, y1: float) -> float:
    return math.log(max(y1, 1e-3) / max(y0, 1e-3)) / math.log(x1 / x0)


def main(max_rows: int = 1_000_000) -> None:
    sizes = [n for n in (10_000, 100_000, 1_000_000) if n <= max_rows]
    with tempfile.TemporaryDirectory(prefix="robocal-bench-replay-") as tmp:
        d = Path(tmp)
        urdf = d / "lite.urdf"
        urdf.write_text(lite_urdf_text())
        base_rss, _ = run_child("import", "-", str(urdf), "-")
        print(f"import only: peak RSS {base_rss:.1f} MiB (subtracted below)")
        rows = []
        for n in sizes:
            csv = d / f"rec{n}.csv"
            write_csv(csv, n)
            mb = csv.stat().st_size / 1e6
            rss, dt = run_child("sweep", str(csv), str(urdf), str(d / f"cal{n}.yaml"))
            whole, wdt = run_child("whole", str(csv), str(urdf), "-")
            rows.append((n, rss - base_rss, dt, whole - base_rss))
            print(
                f"{n:>9} rows {mb:6.1f} MB: streamed sweep +{rss - base_rss:7.1f} MiB, {dt:6.2f} s "
                f"({n / dt:>9,.0f} rows/s) | baseline whole read +{whole - base_rss:7.1f} MiB, {wdt:6.2f} s",
                flush=True,
            )
            csv.unlink()
        for (n0, m0, t0, w0), (n1, m1, t1, w1) in itertools.pairwise(rows):
            print(
                f"slope {n0:>9} -> {n1:>9} rows: memory {slope(n0, m0, n1, m1):+.2f} (0 = bounded), "
                f"time {slope(n0, t0, n1, t1):+.2f} (1 = linear); baseline memory {slope(n0, w0, n1, w1):+.2f}"
            )


if __name__ == "__main__":
    if len(sys.argv) > 1 and sys.argv[1] == "--child":
        child(*sys.argv[2:6])
    else:
        main(int(sys.argv[1]) if len(sys.argv) > 1 else 1_000_000)
