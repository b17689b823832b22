"""Fault-injection soak (issue 26 item 5): ``python benchmarks/run.py faults --trials 1000 [--seed S] [--joints J]``.

Each trial starts a simulated arm (``robocal sim``, its own process), runs ``robocal lerobot calibrate --auto``
against it and injects one fault at a random instant of a random phase; the oracle is the simulator's state (see
``tests/faults/harness.py``). Prints one line per trial, then the counts per fault × phase (pass/fail/not reached).
"""

from __future__ import annotations

import argparse
import signal
import subprocess
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from tests.faults.harness import ROBOTS
from tests.faults.soak import soak, table


def _busy_sibling() -> subprocess.Popen[bytes]:
    """A process that spins on a CPU at the soak's own priority: every trial's processes compete with it."""
    return subprocess.Popen([sys.executable, "-c", "while True: pass"], stdin=subprocess.DEVNULL)


def main(argv: list[str] | None = None) -> None:
    """Run the soak; ``argv``: ``--trials N`` (default 8), ``--seed S``, ``--robots a,b``, ``--joints J``,
    ``--jobs K`` (trials at once), ``--minutes M`` (start no new trial after M minutes), ``--busy N`` (N busy
    siblings spinning on the CPU meanwhile: the "with CPU load" half of the soak); or, with ``--early N``,
    N signals at random instants (up to ``--max-delay-ms``) of ``robocal check --help``'s start-up, counted per
    50 ms: what ended it (Python's own start-up, robocal's one line, the finished command, anything wrong); or,
    with ``--sweep-ctrl-c N``, N hand sweeps (``robocal sweep`` on ``sim:lite``) with one Ctrl-C each at a random
    instant, judged as ``tests/faults/test_sweep_interrupts.py`` does."""
    parser = argparse.ArgumentParser(prog="bench_faults")
    parser.add_argument("--trials", type=int, default=8)
    parser.add_argument("--seed", type=int, default=26)
    parser.add_argument("--robots", default=",".join(ROBOTS))
    parser.add_argument("--joints", default=None, help="search only these joints (shorter trials)")
    parser.add_argument("--jobs", type=int, default=1, help="trials at once (each its own simulator process)")
    parser.add_argument("--minutes", type=float, default=None, help="start no new trial after this long")
    parser.add_argument(
        "--early", type=int, default=0, help="instead: N signals at random instants of a robocal's start-up"
    )
    parser.add_argument("--max-delay-ms", type=float, default=600.0, help="--early: instants up to this")
    parser.add_argument(
        "--sweep-ctrl-c", type=int, default=0, help="instead: N hand sweeps, one Ctrl-C each at a random instant"
    )
    parser.add_argument(
        "--busy", type=int, default=0, help="N busy siblings (a process spinning on a CPU) while the soak runs"
    )
    args = parser.parse_args(argv or [])
    if args.sweep_ctrl_c:
        import tempfile

        from tests.faults.test_sweep_interrupts import random_ctrl_c

        with tempfile.TemporaryDirectory(prefix="robocal-ctrl-c-") as tmp:
            failures = random_ctrl_c(Path(tmp), args.sweep_ctrl_c, args.seed, keep_going=True)
        print(f"{args.sweep_ctrl_c} sweeps, one Ctrl-C each: {len(failures)} failed", *failures, sep="\n")
        return
    if args.early:
        import tempfile

        from tests.faults.early import measure

        with tempfile.TemporaryDirectory(prefix="robocal-early-") as tmp:
            print(measure(args.early, args.seed, args.max_delay_ms / 1000.0, Path(tmp)))
        return
    signal.signal(signal.SIGTERM, signal.default_int_handler)  # kill: the trial's processes are cleaned up
    t0 = time.monotonic()
    busy = [_busy_sibling() for _ in range(args.busy)]
    try:
        results = soak(
            args.trials,
            args.seed,
            tuple(args.robots.split(",")),
            args.joints,
            jobs=args.jobs,
            stop_after_s=None if args.minutes is None else 60.0 * args.minutes,
        )
    finally:
        for proc in busy:
            proc.kill()
            proc.wait()
    print(
        f"\n{len(results)} trials in {time.monotonic() - t0:.0f} s (seed {args.seed}, {args.busy} busy "
        f"siblings); pass/fail/not-reached:"
    )
    print(table(results))
    if any(r.robot.startswith("openarm") for r in results):
        from tests.faults.damiao_harness import limp_summary

        print(limp_summary())
    failed = [r for r in results if r.verdict == "fail"]
    print(f"failed: {len(failed)}; passed: {sum(r.verdict == 'pass' for r in results)}; "
          f"not reached: {sum(r.verdict == 'not-reached' for r in results)}; "
          f"finished with exit 0 despite a signal: {sum(r.finished_despite for r in results)}")  # fmt: skip


if __name__ == "__main__":
    main(sys.argv[1:])
