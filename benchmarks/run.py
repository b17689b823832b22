"""Run the benchmarks: ``.venv/bin/python benchmarks/run.py [NAME ...]``.

Without a name it runs the fast set (each benchmark a few seconds to a few minutes, about 20 minutes in all); the
long runs (the acceptance runs, thousands of seeded simulator runs, and the scaling run to 10^6 joints; up to an
hour and more) run only when named. ``--list`` prints every name
with its set and expected duration. An unknown name is refused (exit 2) before anything runs. Arguments from the
first ``--option`` on go to each named benchmark's ``main(argv)`` (``python benchmarks/run.py faults --trials
1000``).
"""

from __future__ import annotations

import importlib.util
import sys
import time
import traceback
from dataclasses import dataclass
from pathlib import Path

HERE = Path(__file__).resolve().parent


@dataclass(frozen=True)
class Benchmark:
    """One ``bench_<name>.py``.

    Attributes:
        name: What ``run.py`` takes (the file name without ``bench_`` and ``.py``).
        long: True for a long run (acceptance, scaling): only run when named.
        duration: Expected wall time on a 2-core machine shared with other work (measured 2026-11-28, load
            average 11-17; an idle machine is faster), as text.
        what: What it measures, one line.
    """

    name: str
    long: bool
    duration: str
    what: str


BENCHMARKS = (
    Benchmark("jointmap", False, "~5 s", "per-tick and batch joint mapping vs a Python loop / numpy.copyto"),
    Benchmark(
        "lerobot", False, "~10 s", "LeRobot normalize/unnormalize vs LeRobot's loop; SYNC_READ vs READs"
    ),
    Benchmark("ur", False, "~50 s", "batched DH forward kinematics, correction, hash"),
    Benchmark("sweep", False, "~30 s", "sweep tracking and replay throughput"),
    Benchmark("kinematics", False, "~4 min", "identification of 200 poses; accuracy over seeds 0-19"),
    Benchmark("dataset", False, "~4 min", "dataset recalibration vs a plain pyarrow copy (2,000,000 frames)"),
    Benchmark("replay", False, "~8 min", "replay memory and time for 10^4 ... 10^6 rows (180 MB temp file)"),
    Benchmark("view", False, "~2 min", "robocal view in headless Chromium vs bare viser"),
    Benchmark(
        "health_live", False, "~3 min", "live monitor per tick vs numpy.subtract; 10 h of teleoperation, detection"
    ),
    Benchmark(
        "scaling", True, "~65 min", "every file operation for 10^3 ... 10^6 joints (20 s budget per size)"
    ),
    Benchmark(
        "kinematics_tag_prior", True, "~15 min", "camera-session plans with and without --prior (docs table)"
    ),
    Benchmark("autocal", True, "~5 min", "auto-calibration acceptance, 100 seeds per scenario and robot"),
    Benchmark(
        "autocal_wire", True, "~30 min", "auto-calibration over python-can, 100 whole-Lite runs per scenario"
    ),
    Benchmark(
        "autocal_servo", True, "~65 min", "auto-calibration on the servo firmware, 100 runs per SO-101 joint"
    ),
    Benchmark(
        "health", True, "~35 min", "dataset health: recall / false alarms per offset and joint, 200 sessions per arm (again with the calibration files) + 88 for the sag fit"
    ),
    Benchmark(
        "openarm", True, "~3 min", "zero-touch calibration of the simulated OpenArm v10: 20 seeded whole-arm runs"
    ),
    Benchmark(
        "health_verify", True, "~5 min", "lerobot calibrate --auto --verify: 20 seeded injected drifts vs --auto"
    ),
    Benchmark(
        "faults", True, "20-150 s a trial", "fault injection soak (--trials N): counts per fault x phase"
    ),
)
"""Every benchmark, fast set first."""

BY_NAME = {b.name: b for b in BENCHMARKS}
FAST_SET = tuple(b.name for b in BENCHMARKS if not b.long)
"""What a run without names runs."""


def listing() -> str:
    """Every benchmark with its set and expected duration (what ``--list`` prints)."""
    lines = ["benchmarks (python benchmarks/run.py NAME ...; no name: the fast set):"]
    for b in BENCHMARKS:
        kind = "long, by name only" if b.long else "fast set"
        lines.append(f"  {b.name:22s} {b.duration:>8s}  {kind:24s}  {b.what}")
    return "\n".join(lines)


def _run(name: str, options: list[str] | None = None) -> str | None:
    """Run one benchmark; None when it passed, else why it failed (the others still run)."""
    print(f"== {name} ==", flush=True)
    t0 = time.perf_counter()
    failure = None
    try:
        path = HERE / f"bench_{name}.py"
        spec = importlib.util.spec_from_file_location(path.stem, path)
        assert spec is not None and spec.loader is not None
        module = importlib.util.module_from_spec(spec)
        sys.modules[path.stem] = module  # dataclasses look their module up while the class is made
        spec.loader.exec_module(module)
        if options:
            module.main(options)
        else:
            module.main()
    except SystemExit as exc:  # a benchmark below its target says so this way
        if exc.code not in (None, 0):
            failure = str(exc.code)
    except Exception as exc:  # reported, and the other benchmarks still run
        traceback.print_exc()
        failure = f"{type(exc).__name__}: {exc}"
    print(f"({name}: {time.perf_counter() - t0:.1f} s)\n", flush=True)
    return failure


def main(argv: list[str]) -> int:
    """Run the named benchmarks (or the fast set).

    Returns:
        0 when every one ran and met its target, 1 when one failed (the rest still ran), 2 for an unknown name or
        option (before anything runs).
    """
    if any(a in ("-h", "--help", "--list") for a in argv):
        print(__doc__.strip().splitlines()[0])
        print(listing())
        return 0
    split = next((i for i, a in enumerate(argv) if a.startswith("--")), len(argv))
    argv, options = argv[:split], argv[split:]
    if options and not argv:
        print("error: options (--...) go to a named benchmark: run.py NAME --option ...", file=sys.stderr)
        return 2
    unknown = [a for a in argv if a not in BY_NAME]
    if unknown:
        print(
            f"error: unknown benchmark{'s' if len(unknown) > 1 else ''} {', '.join(repr(a) for a in unknown)}; "
            f"valid: {', '.join(BY_NAME)} "
            "(--list shows what each measures and how long it takes)",
            file=sys.stderr,
        )
        return 2
    names = list(dict.fromkeys(argv)) or list(FAST_SET)
    if not argv:
        long_runs = ", ".join(f"{b.name} ({b.duration})" for b in BENCHMARKS if b.long)
        print(
            f"the fast set: {', '.join(FAST_SET)}; the long runs only by name: {long_runs}\n",
            flush=True,
        )
    failed = {}
    for name in names:
        why = _run(name, options) if options else _run(name)
        if why is not None:
            failed[name] = why
    for name, why in failed.items():
        print(f"FAILED {name}: {why}", file=sys.stderr)
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
