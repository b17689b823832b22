"""Calibration health of teleoperation datasets (issue 30): recall and false alarms on simulated sessions.

``python benchmarks/run.py health`` (``HEALTH_SEEDS=N`` sessions per robot, default 200; ``HEALTH_ROBOTS=so101``
for one robot) simulates SO-101 and Koch leader/follower sessions (:mod:`robocal.dataset.teleop_sim`: a human-like
leader, the follower as a position-controlled servo with LeRobot's gains, gravity, friction, backlash, stops and
encoder ticks), writes each as a LeRobot v3 root with its truth, checks them all through datatrove
(:mod:`robocal.workflows.dataset.health_cluster`, 2 tasks) and compares every report with the truth.

Per robot, the sessions cycle through: no fault; a single-joint calibration offset of 0.5, 1, 2, 5 or 17° (random
sign, on the leader or the follower, on a joint with stops); an encoder slip of 5–15° in one episode; values
clipped 4–10° short of a stop; a mirrored sign. It prints, per offset and joint, how often the joint is flagged
``offset`` (named), split by what the data could show: the follower's stop held it harder than its friction could
(``pressed``: the simulator's stop torque, kept 0.2 s, past ``2·τ_stiction``, as goal error ``τ/kp``), its goal
went past the stop but gravity and friction took it (``touched``: the stop held it by less), the leader came within
10° of the range end where the offset would pin the follower (``within 10°``), neither; how
often the interval holds the truth; how often an offset the data cannot show is reported ``ok`` (it must be
``unobservable``); the false-alarm rate on fault-free sessions; and slips located to their episode. For the SO-101
(whose URDF has masses) a second set, ``HEALTH_SAG_SEEDS`` sessions (default 88) without any range-end visit,
measures the sag fit alone: 17° and 5° follower offsets and 17° leader offsets on the loaded joints, and
offset-free sessions; and for every session the sag fit's 99 % interval is checked against the follower's true
offset. With calibration files (``HEALTH_FILES=0`` to skip): the offset-free, 5° and 17° sessions are checked
again with the two arms' LeRobot calibrations the generator writes (:mod:`robocal.dataset.teleop_calibration`: an
offset made by a range recorded short at one end), counting the offset joint flagged (``offset`` or ``suspect``)
and named, and the offset-free sessions flagged. ``HEALTH_RANGE_SEEDS=N`` (default 0: skipped) adds N Koch
sessions (seeds 30000…, every fourth offset-free, the others a 5° offset on a random joint with stops, arm and sign)
written both in ``range_m100_100`` (LeRobot's clamps) and in degrees, flagged and named per arm and case.
``HEALTH_SHIFT_SEEDS=N`` (default 100 per robot, 0 skips) offset-free sessions with one joint's ``action`` or
``observation.state`` shifted by 0, 2, 3, 5 or 17° after the recording (random sign, joint and column): named
``offset`` with the shift in the interval (the rest level), and the unshifted ones flagged.
The followers' servos enforce their position limits where the real ones do (the SO-101's STS3215s;
``HEALTH_GOAL_LIMITS=0``: every follower pressed into its stop, the simulator before 2026-11-29).
"""

from __future__ import annotations

import json
import os
import shutil
import tempfile
import time
from collections import defaultdict
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path
from typing import Any

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq

from robocal.backends.sim.teleop import TELEOP_ARMS, TeleopFaults
from robocal.dataset.teleop_sim import generate_teleop_datasets
from robocal.workflows.dataset.health import HealthRequest, evaluate_health
from robocal.workflows.dataset.health_cluster import health_with_datatrove

OFFSETS_DEG = (0.5, 1.0, 2.0, 5.0, 17.0)
_CYCLE = ("clean", "clean", "clean", "o0.5", "o1", "o2", "o5", "o5", "o17", "o17", "slip", "clip", "flip")


def session_faults(robot: str, seed: int) -> TeleopFaults:
    """The fault of session ``seed`` (cycling through :data:`_CYCLE`; joints, signs and sizes drawn)."""
    arm = TELEOP_ARMS[robot]
    rng = np.random.default_rng(10_000 + seed)
    kind = _CYCLE[seed % len(_CYCLE)]
    with_stops = [j for j, lo in zip(arm.joints[:5], arm.stop_lo_deg[:5], strict=True) if np.isfinite(lo)]
    joint = str(rng.choice(with_stops))
    if kind.startswith("o"):
        size = float(kind[1:]) * float(rng.choice([-1.0, 1.0]))
        return TeleopFaults(
            offset_joint=joint, offset_deg=size, offset_arm=str(rng.choice(["leader", "follower"]))
        )
    if kind == "slip":
        return TeleopFaults(
            slip_joint=joint,
            slip_episode=int(rng.integers(0, 6)),
            slip_frame=int(rng.integers(60, 400)),
            slip_deg=float(rng.uniform(5, 15) * rng.choice([-1, 1])),
        )
    if kind == "clip":
        return TeleopFaults(
            clip_joint=joint, clip_end=str(rng.choice(["lo", "hi"])), clip_short_deg=float(rng.uniform(4, 10))
        )
    if kind == "flip":
        return TeleopFaults(flip_joint=joint)
    return TeleopFaults()


def contact_case(t: dict[str, Any], offset_deg: float) -> str:
    """``pressed``, ``touched``, ``within 10°`` or ``far``: what the session let the data show (module docstring)."""
    held = t["held_lo_deg"] if offset_deg > 0 else t["held_hi_deg"]
    # a follower whose servo held its goal at a position limit: the part a correct calibration's limit (its hand
    # scatter) would not also have held
    limited = t.get("limited_lo_deg", 0.0) if offset_deg > 0 else t.get("limited_hi_deg", 0.0)
    held = max(held, limited - t.get("scatter_deg", 0.0))
    if held > t["friction_span_deg"]:
        return "pressed"
    if t["follower_contact"]:
        return "touched"
    end_gap = t["approach_lo_deg"] if offset_deg > 0 else t["approach_hi_deg"]
    return "within 10°" if end_gap is not None and end_gap <= 10 else "far"


def _rate(hits: int, n: int) -> str:
    return f"{hits}/{n} ({100.0 * hits / n:.0f} %)" if n else "-"


def evaluate(robot: str, seeds: list[int], folder: Path) -> dict[str, Any]:
    """Simulate, check and score ``seeds`` for ``robot``."""
    faults = [session_faults(robot, s) for s in seeds]
    t0 = time.perf_counter()
    roots = []
    for chunk in range(0, len(seeds), 50):  # bounded memory: 50 sessions integrated at a time
        roots += generate_teleop_datasets(
            folder, robot, seeds[chunk : chunk + 50], faults[chunk : chunk + 50], calibration_files=True,
            goal_limits=os.environ.get("HEALTH_GOAL_LIMITS", "1") == "1",
        )  # fmt: skip
    t_sim = time.perf_counter() - t0
    t0 = time.perf_counter()
    # the datasets are in degrees (LeRobot's use_degrees; Koch's default is range_m100_100)
    reports = health_with_datatrove(roots, folder / "reports", use_degrees=True, tasks=2, workers=2)
    t_check = time.perf_counter() - t0
    print(
        f"{robot}: {len(seeds)} sessions simulated and written in {t_sim:.0f} s, checked in {t_check:.0f} s"
    )
    score: dict[str, Any] = {
        "offset": defaultdict(lambda: defaultdict(int)),
        "clean": [0, 0],
        "clean_joint": defaultdict(int),
        "slip": [0, 0],
        "clip": [0, 0],
        "clip_unseen": [0, 0],
        "flip": [0, 0],
        "errors": 0,
        "sag_cover": defaultdict(lambda: [0, 0]),
        "by_arm": defaultdict(lambda: [0, 0, 0]),
        "files": defaultdict(lambda: [0, 0, 0]),
    }
    if os.environ.get("HEALTH_FILES", "1") != "0":
        _score_with_files(robot, roots, faults, score["files"])
    for root, rep_path, f in zip(roots, reports, faults, strict=True):
        rep = json.loads(rep_path.read_text())
        truth = json.loads(root.with_name(root.name + ".truth.json").read_text())
        if "error" in rep:
            score["errors"] += 1
            continue
        joints = rep["joints"]
        flagged = [n for n, j in joints.items() if j["status"] in ("offset", "suspect")]
        if f.slip_joint is None and f.clip_joint is None and f.flip_joint is None:
            # the sag fit measures the follower's own offset (0 unless the follower's calibration is off)
            for name, jr in joints.items():
                sag = jr.get("sag")
                if sag is None:
                    continue
                e_f = f.offset_deg if (f.offset_joint == name and f.offset_arm == "follower") else 0.0
                c = score["sag_cover"][(name, "offset-free" if e_f == 0.0 else f"{abs(e_f):g}°")]
                c[1] += 1
                c[0] += sag["ci99_deg"][0] - 1e-6 <= e_f <= sag["ci99_deg"][1] + 1e-6
        if f.offset_joint is not None:
            t = truth["joints"][f.offset_joint]
            o = t["offset_deg"]
            case = contact_case(t, o)
            key = (abs(o), f.offset_joint, case)
            j = joints[f.offset_joint]
            s = score["offset"][key]
            s["n"] += 1
            s["named"] += j["status"] == "offset"
            s["flagged_named"] += j["status"] in ("offset", "suspect") and flagged == [f.offset_joint]
            s["wrong_sign"] += j["status"] == "offset" and j["offset_deg"] is not None and j["offset_deg"] * o < 0
            s["flagged"] += bool(flagged)
            s["ok_wrongly"] += j["status"] == "ok" and abs(o) >= 2.0
            s["others"] += any(n != f.offset_joint for n in flagged)
            arm_case = score["by_arm"][(abs(o), case, f.offset_arm)]
            arm_case[0] += j["status"] == "offset"
            arm_case[1] += 1
            arm_case[2] += j["status"] in ("offset", "suspect") and flagged == [f.offset_joint]
            ci = j["ci_deg"]
            s["ci_n"] += ci is not None and j["status"] == "offset"
            s["ci_hit"] += ci is not None and j["status"] == "offset" and ci[0] - 1e-6 <= o <= ci[1] + 1e-6
        elif f.slip_joint is not None:
            score["slip"][1] += 1
            jumps = joints[f.slip_joint]["jumps"]
            score["slip"][0] += any(
                jp["episode"] == f.slip_episode and abs(jp["frame"] - f.slip_frame) <= 2 for jp in jumps
            )
        elif f.clip_joint is not None:
            t = truth["joints"][f.clip_joint]
            gap = t["approach_hi_deg"] if f.clip_end == "hi" else t["approach_lo_deg"]
            key = "clip" if gap is not None and gap < f.clip_short_deg - 1.0 else "clip_unseen"
            score[key][1] += 1
            score[key][0] += joints[f.clip_joint]["status"] == "suspect"
        elif f.flip_joint is not None:
            score["flip"][1] += 1
            score["flip"][0] += joints[f.flip_joint]["status"] == "suspect"
        else:
            score["clean"][1] += 1
            score["clean"][0] += bool(flagged)
            for n in flagged:
                score["clean_joint"][n] += 1
    return score


def _check_with_files(job: tuple[str, str]) -> dict[str, Any]:
    root, robot_type = Path(job[0]), job[1]
    _, rep = evaluate_health(
        HealthRequest(
            root,
            root.with_name(root.name + ".health.json"),
            robot=robot_type,
            use_degrees=True,
            leader_calibration=root.with_name(root.name + ".leader.json"),
            follower_calibration=root.with_name(root.name + ".follower.json"),
        )
    )
    return rep


def _score_with_files(robot: str, roots: list[Path], faults: list[TeleopFaults], out: Any) -> None:
    """Check the offset-free, 5° and 17° sessions again with the two calibration files (2 processes)."""
    picked = [
        (r, f)
        for r, f in zip(roots, faults, strict=True)
        if f.slip_joint is None and f.clip_joint is None and f.flip_joint is None
        and (f.offset_joint is None or abs(f.offset_deg) >= 5.0)
    ]
    t0 = time.perf_counter()
    with ProcessPoolExecutor(2) as pool:
        reports = list(pool.map(_check_with_files, [(str(r), TELEOP_ARMS[robot].robot_type) for r, _ in picked]))
    print(f"{robot}: {len(picked)} sessions checked with their calibration files in {time.perf_counter() - t0:.0f} s")
    for (root, f), rep in zip(picked, reports, strict=True):
        if f.offset_joint is None:
            c = out[("offset-free", "", "")]
            c[0] += bool(rep["flagged"])
            c[1] += 1
            continue
        truth = json.loads(root.with_name(root.name + ".truth.json").read_text())["joints"][f.offset_joint]
        case = "contact" if truth["follower_contact"] else "no contact"
        j = rep["joints"][f.offset_joint]
        c = out[(f"{abs(f.offset_deg):g}°", f.offset_joint, case)]
        c[0] += j["status"] in ("offset", "suspect") and all(n == f.offset_joint for n in rep["flagged"])
        c[1] += 1
        c[2] += j["status"] == "offset"


def print_score(robot: str, score: dict[str, Any]) -> None:
    """The tables of one robot."""
    print(
        f"\n-- {robot}: offsets (named: 'offset' on the right joint, its interval holding the truth; flagged: "
        "'offset' or 'suspect' on the right joint and no other) --"
    )
    print(
        f"{'offset':>7s} {'joint':14s} {'case':11s} {'named':>14s} {'CI holds':>12s} {'flagged':>14s} "
        f"{'wrong sign':>10s} {'ok (wrong)':>10s} {'other joint':>11s}"
    )
    by_case: dict[tuple[float, str], list[int]] = defaultdict(lambda: [0, 0, 0, 0])
    for (size, joint, case), s in sorted(score["offset"].items()):
        print(
            f"{size:7.1f} {joint:14s} {case:11s} {_rate(s['named'], s['n']):>14s} "
            f"{_rate(s['ci_hit'], s['ci_n']):>12s} {_rate(s['flagged_named'], s['n']):>14s} {s['wrong_sign']:>10d} "
            f"{s['ok_wrongly']:>10d} {s['others']:>11d}"
        )
        c = by_case[(size, case)]
        c[0] += s["named"]
        c[1] += s["n"]
        c[2] += s["flagged_named"]
        c[3] += s["wrong_sign"]
    print(f"\n-- {robot}: offsets, all joints --")
    for (size, case), (hit, n, flag, wrong) in sorted(by_case.items()):
        print(f"{size:7.1f}° {case:11s} named {_rate(hit, n):>14s}  flagged {_rate(flag, n):>14s}  wrong sign {wrong}")
    print(f"\n-- {robot}: offsets, by the arm whose calibration is off (the sag sees only the follower's) --")
    for (size, case, arm), (hit, n, flag) in sorted(score["by_arm"].items()):
        print(f"{size:7.1f}° {case:11s} {arm:9s} named {_rate(hit, n):>14s}  flagged {_rate(flag, n)}")
    print(f"\n-- {robot}: sag fit, its 99 % interval holds the follower's true offset --")
    for (name, what), (hit, n) in sorted(score["sag_cover"].items()):
        print(f"{name:14s} {what:11s} {_rate(hit, n)}")
    hit, n = score["clean"]
    print(
        f"\nfault-free sessions flagged (false alarms): {_rate(hit, n)}; by joint: {dict(score['clean_joint'])}"
    )
    print(f"slips located to their episode and frame (±2): {_rate(*score['slip'])}")
    print(f"clipped values flagged suspect, the leader past the clipped value: {_rate(*score['clip'])}; "
          f"never past it: {_rate(*score['clip_unseen'])}")
    print(f"mirrored signs flagged suspect: {_rate(*score['flip'])}")
    if score["files"]:
        print(f"\n-- {robot}: with the calibration files (flagged and named: offset or suspect, no other joint) --")
        for (size, joint, case), (hit, n, off) in sorted(score["files"].items()):
            if size == "offset-free":
                print(f"offset-free sessions flagged: {_rate(hit, n)}")
            else:
                print(f"{size:>4s} {joint:14s} {case:11s} named {_rate(hit, n):>14s}  of them 'offset' {off}")
    print(f"datasets refused: {score['errors']}")


_SAG_CYCLE = (
    ("follower", 17.0, "shoulder_lift"),
    ("follower", 17.0, "elbow_flex"),
    ("follower", 17.0, "wrist_flex"),
    ("follower", 5.0, "shoulder_lift"),
    ("follower", 5.0, "elbow_flex"),
    ("follower", 5.0, "wrist_flex"),
    ("leader", 17.0, "shoulder_lift"),
    ("leader", 17.0, "elbow_flex"),
    ("leader", 17.0, "wrist_flex"),
    ("clean", 0.0, ""),
    ("clean", 0.0, ""),
)


def evaluate_sag(robot: str, n: int, folder: Path) -> None:
    """Sessions without range-end visits (``p_end`` 0): what the sag fit alone sees (a URDF with masses only)."""
    seeds = list(range(5000, 5000 + n))
    cases = [_SAG_CYCLE[i % len(_SAG_CYCLE)] for i in range(n)]
    rng = np.random.default_rng(77)
    faults = [
        TeleopFaults()
        if arm == "clean"
        else TeleopFaults(offset_joint=j, offset_deg=size * float(rng.choice([-1.0, 1.0])), offset_arm=arm)
        for arm, size, j in cases
    ]
    t0 = time.perf_counter()
    roots = generate_teleop_datasets(folder, robot, seeds, faults, p_end=0.0)
    reports = health_with_datatrove(roots, folder / "reports", use_degrees=True, tasks=2, workers=2)
    print(f"\n-- {robot}: no range-end visits, {n} sessions ({time.perf_counter() - t0:.0f} s): the sag fit --")
    tally: dict[tuple[str, float, str], list[int]] = defaultdict(lambda: [0, 0, 0, 0])
    clean = [0, 0]
    for rep_path, f, (arm, size, joint) in zip(reports, faults, cases, strict=True):
        rep = json.loads(rep_path.read_text())
        if arm == "clean":
            clean[1] += 1
            clean[0] += bool(rep["flagged"])
            continue
        j = rep["joints"][joint]
        t = tally[(arm, size, joint)]
        t[0] += j["status"] == "offset"
        t[1] += 1
        t[2] += j["status"] == "ok"
        t[3] += any(n != joint for n in rep["flagged"])
        ci = j["ci_deg"]
        if j["status"] == "offset" and not (ci[0] - 1e-6 <= f.offset_deg <= ci[1] + 1e-6):
            print(f"   interval misses the truth: {rep['dataset']} {joint} {f.offset_deg:+.1f} in {ci}")
    for (arm, size, joint), (hit, total, ok, other) in sorted(tally.items()):
        print(f"{arm:9s} {size:5.1f}° {joint:14s} named {_rate(hit, total):>12s}  ok (wrong) {ok}  other joint {other}")
    print(f"offset-free sessions flagged: {_rate(*clean)}")


_SHIFTS = (0.0, 2.0, 3.0, 5.0, 17.0)
"""Sizes of the column shifts of :func:`evaluate_shift` (0: the session as recorded)."""


def _shift_column(root: Path, column: str, joint: int, delta: float) -> None:
    for f in (root / "data").rglob("*.parquet"):
        t = pq.read_table(f)
        x = np.asarray(t.column(column).to_pylist(), dtype=np.float32)
        x[:, joint] += delta
        i = t.schema.get_field_index(column)
        pq.write_table(t.set_column(i, column, pa.array(x.tolist(), type=t.schema.field(column).type)), f)


def evaluate_shift(robot: str, n: int, folder: Path) -> None:
    """Offset-free sessions with one joint's ``action`` or ``observation.state`` shifted by a constant after the
    recording (a naive injection, an edited column): what the rest level sees (``core/health/level.py``)."""
    arm = TELEOP_ARMS[robot]
    seeds = list(range(7000, 7000 + n))
    t0 = time.perf_counter()
    roots = generate_teleop_datasets(folder, robot, seeds, [TeleopFaults()] * n)
    rng = np.random.default_rng(78)
    cases = []
    for k, root in enumerate(roots):
        size = _SHIFTS[k % len(_SHIFTS)] * float(rng.choice([-1.0, 1.0]))
        joint = int(rng.integers(0, len(arm.joints) - 1))  # not the gripper: its range mode clamps 0..100
        column = str(rng.choice(["action", "observation.state"]))
        if size:
            _shift_column(root, column, joint, size)
        cases.append((abs(size), arm.joints[joint], size if column == "observation.state" else -size))
    reports = health_with_datatrove(roots, folder / "reports", use_degrees=True, tasks=2, workers=2)
    print(f"\n-- {robot}: one column shifted after the recording, {n} sessions ({time.perf_counter() - t0:.0f} s) --")
    tally: dict[tuple[float, str], list[int]] = defaultdict(lambda: [0, 0, 0, 0])
    for rep_path, (size, joint, truth) in zip(reports, cases, strict=True):
        rep = json.loads(rep_path.read_text())
        j = rep["joints"][joint]
        t = tally[(size, joint)]
        t[1] += 1
        if size == 0:
            t[0] += bool(rep["flagged"])
            continue
        ci = j["ci_deg"]
        t[0] += j["status"] == "offset" and ci is not None and ci[0] - 1e-6 <= truth <= ci[1] + 1e-6
        others = [other for other in rep["flagged"] if other != joint]
        t[2] += bool(others)
        t[3] += j["status"] == "ok"
        for other in others:
            o = rep["joints"][other]
            print(f"   {rep['dataset']}: {joint} {truth:+.0f}° shifted, {other} flagged {o['status']}: {'; '.join(o['reasons'])}")
    for (size, joint), (hit, total, other, ok) in sorted(tally.items()):
        what = "flagged (false alarm)" if size == 0 else "named with the size in the interval"
        print(f"{size:5.1f}° {joint:14s} {what:36s} {_rate(hit, total):>12s}  other joint {other}  ok {ok}")


def range_faults(seed: int) -> TeleopFaults:
    """Session ``seed`` of the range-mode set: every fourth offset-free, the others a 5° offset (drawn)."""
    arm = TELEOP_ARMS["koch"]
    rng = np.random.default_rng(seed)
    if seed % 4 == 0:
        return TeleopFaults()
    with_stops = [j for j, lo in zip(arm.joints[:5], arm.stop_lo_deg[:5], strict=True) if np.isfinite(lo)]
    return TeleopFaults(
        offset_joint=str(rng.choice(with_stops)),
        offset_deg=5.0 * float(rng.choice([-1.0, 1.0])),
        offset_arm=str(rng.choice(["leader", "follower"])),
    )


def evaluate_range_modes(n: int, folder: Path) -> None:
    """Koch sessions in ``range_m100_100`` and in degrees: what LeRobot's clamp leaves the data able to show."""
    seeds = list(range(30000, 30000 + n))
    faults = [range_faults(s) for s in seeds]
    for mode in ("range_m100_100", "degrees"):
        t0 = time.perf_counter()
        degrees = mode == "degrees"
        roots = generate_teleop_datasets(folder / mode, "koch", seeds, faults, use_degrees=degrees)
        reports = health_with_datatrove(roots, folder / mode / "reports", use_degrees=degrees, tasks=2, workers=2)
        tally: dict[tuple[str, str], list[int]] = defaultdict(lambda: [0, 0, 0])
        clean = [0, 0]
        for root, rep_path, f in zip(roots, reports, faults, strict=True):
            rep = json.loads(rep_path.read_text())
            if f.offset_joint is None:
                clean[0] += bool(rep["flagged"])
                clean[1] += 1
                continue
            truth = json.loads(root.with_name(root.name + ".truth.json").read_text())["joints"][f.offset_joint]
            t = tally[(f.offset_arm, contact_case(truth, truth["offset_deg"]))]
            t[0] += rep["joints"][f.offset_joint]["status"] in ("offset", "suspect") and rep["flagged"] == [
                f.offset_joint
            ]
            t[1] += 1
            t[2] += rep["joints"][f.offset_joint]["status"] == "ok"
        print(f"\n-- koch, 5° offsets recorded in {mode} ({len(seeds)} sessions, {time.perf_counter() - t0:.0f} s) --")
        for (arm, case), (hit, total, ok) in sorted(tally.items()):
            print(f"{arm:9s} {case:11s} flagged and named {_rate(hit, total):>14s}  ok (wrong) {ok}")
        print(f"offset-free sessions flagged: {_rate(*clean)}")


def main() -> None:
    n = int(os.environ.get("HEALTH_SEEDS", "200"))
    robots = [r for r in os.environ.get("HEALTH_ROBOTS", "so101,koch").split(",") if r]
    n_sag = int(os.environ.get("HEALTH_SAG_SEEDS", "88"))
    folder = Path(tempfile.mkdtemp(prefix="robocal-health-"))
    try:
        for robot in robots:
            print_score(robot, evaluate(robot, list(range(n)), folder / robot))
            if robot == "so101" and n_sag > 0:  # the robot whose URDF has masses
                evaluate_sag(robot, n_sag, folder / f"{robot}-sag")
        n_shift = int(os.environ.get("HEALTH_SHIFT_SEEDS", "100"))
        for robot in robots if n_shift > 0 else []:
            evaluate_shift(robot, n_shift, folder / f"{robot}-shift")
        n_range = int(os.environ.get("HEALTH_RANGE_SEEDS", "0"))
        if n_range > 0:
            evaluate_range_modes(n_range, folder / "koch-range")
    finally:
        shutil.rmtree(folder, ignore_errors=True)


if __name__ == "__main__":
    main()
