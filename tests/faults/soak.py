"""The fault soak: many seeded trials of ``harness.run_trial``, their table, and the table of a soak's log.

``python benchmarks/run.py faults --trials N`` (``benchmarks/bench_faults.py``) runs it; not part of the test suite.
"""

from __future__ import annotations

import random
import time
from collections import Counter

from .harness import FAULTS, LITE_FAULTS, PHASES, ROBOTS, TrialResult, run_trial

__all__ = ["results_from_log", "soak", "table"]


def soak(
    trials: int,
    seed: int,
    robots: tuple[str, ...] = ROBOTS,
    joints: str | None = None,
    jobs: int = 1,
    stop_after_s: float | None = None,
) -> list[TrialResult]:
    """Run ``trials`` random (robot, fault, phase) trials, seeded; prints one line per trial as it ends.

    The draws are made up front from ``seed`` (each trial gets its own seeded generator for its instants), so a
    trial is the same whether it runs alone or beside others. ``jobs`` trials run at once (each with its own
    simulator process and folder: more load on the machine, which the trials must survive). ``stop_after_s``:
    start no new trial after that many seconds (the ones running finish).
    """
    from concurrent.futures import FIRST_COMPLETED, Future, ThreadPoolExecutor, wait

    rng = random.Random(seed)
    plan = []
    for _ in range(trials):
        robot = rng.choice(robots)
        faults = LITE_FAULTS if robot == "lite" else (*FAULTS, "lost-bus") if "openarm" in robot else FAULTS
        # openarm-zero: right after a zero reached flash; openarm: also the gripper held while J7 is searched
        phases = (*PHASES, "zero-write") if robot == "openarm-zero" else (*PHASES, "held") if robot == "openarm" else PHASES
        fault, phase = rng.choice(faults), rng.choice(phases)
        plan.append((robot, fault, phase, rng.randrange(2**32)))
    results: list[TrialResult] = []
    t_start = time.monotonic()

    def one(i: int) -> TrialResult:
        robot, fault, phase, trial_seed = plan[i]
        t0 = time.monotonic()
        oa_or_lite = robot in ("lite", "openarm", "openarm-zero")
        r = run_trial(robot, fault, phase, random.Random(trial_seed), None if oa_or_lite else joints)
        print(f"[{i + 1}/{trials}] {robot} {fault} @ {phase}: {r.verdict} (exit {r.exit_code}, "
              f"{time.monotonic() - t0:.0f} s) {'; '.join(r.failures)}"
              + (f" [robocal: {r.stderr_tail}]" if r.failures else "")
              + (f"({r.stderr_tail})" if not r.injected and r.stderr_tail else ""), flush=True)  # fmt: skip
        return r

    with ThreadPoolExecutor(max_workers=max(1, jobs)) as pool:
        running: set[Future[TrialResult]] = set()
        next_i = 0
        while next_i < trials or running:
            while next_i < trials and len(running) < max(1, jobs):
                if stop_after_s is not None and time.monotonic() - t_start > stop_after_s:
                    next_i = trials  # no new trial
                    break
                running.add(pool.submit(one, next_i))
                next_i += 1
            if not running:
                break
            done, running = wait(running, return_when=FIRST_COMPLETED)
            results.extend(f.result() for f in done)
    return results


def results_from_log(text: str) -> list[TrialResult]:
    """The trials of a soak's printed lines (``[i/N] ROBOT FAULT @ PHASE: VERDICT (exit C, T s) ...``).

    For a soak stopped early: its table is then made from what it printed.
    """
    import re

    pattern = re.compile(
        r"^\[\d+/\d+\] (\S+) (\S+) @ (\S+): (pass|fail|not-reached) \(exit (-?\d+), [^)]*\) ?(.*)$"
    )
    out = []
    for line in text.splitlines():
        m = pattern.match(line)
        if m:
            robot, fault, phase, verdict, code, rest = m.groups()
            if phase in ("restore", "file-write") and ": FAILED " in rest:
                verdict = "not-reached"  # as _wait_for_phase decides now: the run had failed on its own
            failures = (rest or "failed",) if verdict == "fail" else ()
            out.append(TrialResult(robot, fault, phase, verdict != "not-reached", int(code), failures))
    return out


def table(results: list[TrialResult]) -> str:
    """Counts per fault × phase and per fault over all phases: ``pass/fail/not-reached``; then per robot."""
    counts: Counter[tuple[str, str, str]] = Counter((r.fault, r.phase, r.verdict) for r in results)
    phases = (*PHASES, *sorted({r.phase for r in results} - set(PHASES)))  # openarm-zero: zero-write too
    head = f"{'fault':15s}" + "".join(f"{p:>16s}" for p in (*phases, "all phases"))
    rows = [head]
    for f in (*FAULTS, *sorted({r.fault for r in results} - set(FAULTS))):  # openarm: lost-bus too
        cells = [
            f"{counts[(f, p, 'pass')]}/{counts[(f, p, 'fail')]}/{counts[(f, p, 'not-reached')]}"
            for p in phases
        ]
        total = [sum(counts[(f, p, v)] for p in phases) for v in ("pass", "fail", "not-reached")]
        cells.append("/".join(map(str, total)))
        rows.append(f"{f:15s}" + "".join(f"{c:>16s}" for c in cells))
    per_robot = Counter((r.robot, r.verdict) for r in results)
    for robot in sorted({r.robot for r in results}):
        rows.append(
            f"{robot}: {per_robot[(robot, 'pass')]} pass, {per_robot[(robot, 'fail')]} fail, "
            f"{per_robot[(robot, 'not-reached')]} not reached"
        )
    return "\n".join(rows)
