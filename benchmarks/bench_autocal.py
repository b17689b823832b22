"""Auto-calibration acceptance (issue 11): seeded runs per joint and scenario on the physics plant.

``python benchmarks/run.py autocal`` (100 seeds per scenario and robot; ``AUTOCAL_SEEDS=N`` to change;
``AUTOCAL_SEEDS_PER_JOINT=N`` for N runs of every joint; ``AUTOCAL_ROBOTS=lite`` for one robot;
``AUTOCAL_SCENARIOS=a,b`` for a subset of the scenarios) prints,
per robot and scenario: zero error and span error (mean |e|, max |e|, σ over seeds), outcomes, abort times against
the bound, false stops, peak torque against the cap, and the total simulated time of a whole robot. The test suite
(tests/autocal/test_acceptance.py) runs a few seeds through the same :func:`run_scenario` and :data:`THRESHOLDS`.

Each run is one joint of the robot (seed → joint, cycling through the robot's joints, so every joint gets runs)
auto-calibrated by :func:`robocal.workflows.autocal.job.calibrate_joint` — the workflow code the CLI runs — on a
:class:`PlantDriver`: a drive law like the Robstride MIT one (``kp = cap/max_lag``, small ``kd``, the firmware
torque limit 1.05·cap the Robstride driver sets) stepping :mod:`robocal.backends.sim.physics` for one 10 ms control period per
command. The truth is the plant's own stops: the ideal offset is the midpoint rule applied to the true stop
angles; the zero error is measured − ideal.
"""

from __future__ import annotations

import math
import os
import statistics
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from robocal.backends.sim.physics import Drive, JointPlant, PlantParams, Scenario, make_plant
from robocal.core.profile_auto import AutoJoint, AutoSection
from robocal.core.stop_search import Command, StopSample
from robocal.workflows.autocal.job import calibrate_joint
from robocal.workflows.autocal.model import JointOutcome

PERIOD_S = 0.01
MAX_LAG_RAD = math.radians(3.0)


@dataclass(frozen=True)
class BenchJoint:
    """One joint of a benchmark robot (URDF limits, rad; cap N·m; inertia kg·m²)."""

    name: str
    lower: float
    upper: float
    rated_nm: float
    fraction: float
    inertia: float


def _lite() -> tuple[BenchJoint, ...]:
    from robocal.backends.sim.lite import LITE_JOINTS
    from robocal.core.profile_auto import rated_torque_nm

    out = []
    for j in LITE_JOINTS:
        rated = rated_torque_nm(j.model) or 5.0
        frac = 0.3 if "shoulder_pitch" in j.name else 0.25
        inertia = {"rs-02": 0.05, "rs-00": 0.03, "rs-05": 0.005}.get(j.model, 0.02)
        out.append(BenchJoint(j.name, j.lower, j.upper, rated, frac, inertia))
    return tuple(out)


_SO101_URDF_LIMITS_RAD = {
    "shoulder_pan": (-1.91986, 1.91986),
    "shoulder_lift": (-1.74533, 1.74533),
    "elbow_flex": (-1.69, 1.69),
    "wrist_flex": (-1.65806, 1.65806),
    "wrist_roll": (-2.74385, 2.84121),
    "gripper": (-0.174533, 1.74533),
}
_SO101_INERTIA_KGM2 = {
    "shoulder_pan": 0.004,
    "shoulder_lift": 0.004,
    "elbow_flex": 0.003,
    "wrist_flex": 0.002,
}


def _so101() -> tuple[BenchJoint, ...]:
    """SO-101 joints: so101_new_calib URDF limits; rating and search fraction from the profile robocal ships.

    The rating is the STS3215 7.4 V stall torque (``robocal.backends.servo_ratings``, 1.91 N·m) and each joint's
    fraction the ``so101_follower`` profile's (45 % shoulder_lift, 40 % elbow_flex, 25 % the others), as
    ``lerobot calibrate --auto`` searches them.
    """
    from robocal.backends.servo_ratings import RATINGS
    from robocal.workflows.lerobot import robot_spec
    from robocal.workflows.lerobot.auto import auto_section

    arm = robot_spec("so101_follower")
    section = auto_section("so101_follower")
    out = []
    for name, (lower, upper) in _SO101_URDF_LIMITS_RAD.items():
        aj = section.joint(name)
        assert aj is not None
        rated = RATINGS[arm.motors[arm.motor_names.index(name)].model].stall_torque_nm
        out.append(
            BenchJoint(name, lower, upper, rated, aj.torque_fraction, _SO101_INERTIA_KGM2.get(name, 0.001))
        )
    return tuple(out)


SO101 = _so101()


@dataclass(frozen=True)
class ScenarioSpec:
    """A benchmark scenario: the plant scenario, stiffness, and what is expected."""

    name: str
    scenario: Scenario
    stiffness: float = 600.0
    expect: str = "accurate"  # accurate | abort | span_mismatch
    zero_tol_deg: float = 0.5
    span_tol_deg: float = 1.0
    gravity_fraction: float = 0.0  # gravity torque amplitude as a fraction of the cap
    # every run that found its stops confirmed one of them by this test: the fault really happened and was
    # recovered from (an overload latch that never tripped would pass the scenario without testing anything)
    confirmed_by: str = ""

    def plant_scenario(self, cap_nm: float) -> Scenario:
        """The plant scenario of a joint searched with ``cap_nm``: with its gravity torque when there is one."""
        if not self.gravity_fraction:
            return self.scenario
        return Scenario(**{**self.scenario.__dict__, "gravity_nm": self.gravity_fraction * cap_nm})


SCENARIOS: tuple[ScenarioSpec, ...] = (
    ScenarioSpec("stiff_1000", Scenario(), stiffness=1000.0),
    ScenarioSpec("stiff_100", Scenario(), stiffness=100.0),
    ScenarioSpec("asymmetric", Scenario(asymmetric_stops=True), stiffness=300.0),
    ScenarioSpec("gravity", Scenario(), stiffness=300.0, gravity_fraction=0.3),
    ScenarioSpec(
        "soft_15_gravity", Scenario(soft_stop=True), zero_tol_deg=1.5, span_tol_deg=1.5, gravity_fraction=0.3
    ),
    ScenarioSpec("stiction_0.8", Scenario(stiction_ratio=0.8), stiffness=300.0),
    # the motor-side encoder sees the 1° play on both sides: the span grows by ~1°, the midpoint does not move
    ScenarioSpec(
        "backlash_1deg", Scenario(backlash_rad=math.radians(1.0)), stiffness=300.0, span_tol_deg=1.5
    ),
    ScenarioSpec(
        "overload_latch", Scenario(overload_latch=True), stiffness=300.0, confirmed_by="overload+reread"
    ),
    ScenarioSpec(
        "silent_at_stop", Scenario(silent_at_stop=True), stiffness=300.0, confirmed_by="no-reply+reread"
    ),
    ScenarioSpec("missing_stop", Scenario(missing_stop="upper"), expect="abort"),
    ScenarioSpec("obstacle", Scenario(obstacle=True), expect="span_mismatch"),
    ScenarioSpec("cable_snag", Scenario(cable_snag=True), expect="span_mismatch"),
)

THRESHOLDS = {
    "sigma_deg": 0.1,
    "peak_over_cap": 1.10,
    "abort_margin_s": 2.0,
    "lite_total_s": 180.0,
    "so101_total_s": 60.0,
}
"""Issue 11 "Done when" numbers (zero/span tolerances are per scenario)."""


class PlantDriver:
    """A joint driver over a :class:`JointPlant` with the Robstride-MIT-like law (see the module docstring)."""

    def __init__(self, name: str, plant: JointPlant, cap_nm: float, max_lag_rad: float = MAX_LAG_RAD) -> None:
        self.name = name
        self.plant = plant
        self.cap = cap_nm
        self.kp = cap_nm / max_lag_rad
        self.kd = 0.05 * cap_nm
        self.tau_max = 1.05 * cap_nm  # the firmware torque limit the Robstride driver sets (limit_torque)
        self.drive = Drive()
        self.limped = False

    def _sample(self) -> StopSample:
        r = self.plant.read()
        if not r.answers:
            return StopSample(r.t_s, math.nan, ok=False)
        return StopSample(r.t_s, r.q_rad, r.v_rad_s, r.tau_nm, True, r.overload)

    def read(self) -> StopSample:
        return self._sample()

    def execute(self, cmd: Command) -> StopSample:
        if cmd.action == "limp":
            self.limp()
        elif cmd.action == "reread":
            self.plant.clear_overload()
            self.drive = Drive(kd_nms_rad=self.kd, tau_max_nm=self.tau_max)
        elif cmd.action == "push":
            sign = 1.0 if cmd.q_target_rad >= self.plant.q_rad else -1.0
            self.drive = Drive(
                kd_nms_rad=self.kd, tau_ff_nm=sign * cmd.torque_limit_nm, tau_max_nm=self.tau_max
            )
        else:
            kp = self.kp * min(1.0, cmd.torque_limit_nm / self.cap)
            self.drive = Drive(kp, self.kd, cmd.q_target_rad, cmd.v_target_rad_s, 0.0, self.tau_max)
        self.plant.advance(PERIOD_S, self.drive)
        return self._sample()

    def limp(self) -> None:
        self.drive = Drive()
        self.limped = True


@dataclass
class RunResult:
    """One seeded run."""

    joint: str
    code: str
    zero_err_deg: float = math.nan
    span_err_deg: float = math.nan
    time_s: float = math.nan
    abort_time_s: float = math.nan
    abort_bound_s: float = math.nan
    peak_over_cap: float = math.nan
    limp_at_end: bool = False
    tests: tuple[str, ...] = ()

    @classmethod
    def from_outcome(
        cls,
        out: JointOutcome,
        *,
        limp_at_end: bool,
        peak_tau_nm: float,
        cap_nm: float,
        speed_rad_s: float,
        abort_span_rad: float,
        tolerance_deg: float = 15.0,
    ) -> RunResult:
        """What every bench records of a joint's outcome (the zero and span errors are the caller's).

        The verdict, the time, whether the joint was limp at the end, its peak motor torque over the cap, the
        tests that found its stops and, when a search failed, how long that search took against its bound: the
        expected span plus ``tolerance_deg`` at ``speed_rad_s``.
        """
        found = (out.stops.lower, out.stops.upper)
        res = cls(out.name, out.stops.code, time_s=out.time_s, limp_at_end=limp_at_end)
        res.peak_over_cap = peak_tau_nm / cap_nm
        res.tests = tuple(r.test for r in found if r is not None and r.ok)
        failed = [r for r in found if r is not None and not r.ok]
        if failed:
            res.abort_time_s = failed[0].duration_s
            res.abort_bound_s = (abort_span_rad + math.radians(tolerance_deg)) / speed_rad_s
        return res


def _section(j: BenchJoint) -> tuple[AutoJoint, AutoSection]:
    aj = AutoJoint(j.name, "both", j.rated_nm, j.fraction, 20.0, 15.0)
    return aj, AutoSection(joints=(aj,))


def run_one(robot: Sequence[BenchJoint], spec: ScenarioSpec, seed: int) -> RunResult:
    """Auto-calibrate one joint (``robot[seed % len]``) in scenario ``spec`` with ``seed``."""
    j = robot[seed % len(robot)]
    aj, section = _section(j)
    cap = aj.torque_cap_nm
    rng = np.random.default_rng(10_000 + seed)
    z = float(rng.uniform(-0.5, 0.5))  # the unknown zero: the plant's frame is the joint frame + z
    nominal = PlantParams(
        inertia_kgm2=j.inertia,
        coulomb_nm=0.03 * cap,
        stiction_nm=0.05 * cap,
        viscous_nms_rad=0.02 * cap,
        stop_lower_rad=j.lower + z,
        stop_upper_rad=j.upper + z,
        stiffness_lower=spec.stiffness,
        stiffness_upper=spec.stiffness,
        noise_rad=math.radians(0.02),
    )
    scen = spec.plant_scenario(cap)
    span = j.upper - j.lower
    q0 = j.lower + z + float(rng.uniform(0.2, 0.5)) * span
    plant = make_plant(scen, nominal, search_torque_nm=cap, seed=seed, q0_rad=q0)
    driver = PlantDriver(j.name, plant, cap)
    gravity: Callable[[float], float] | None = plant.gravity_nm if plant.params.gravity_nm else None
    out = calibrate_joint(driver, aj, section, (j.lower, j.upper), max_lag_rad=MAX_LAG_RAD, gravity=gravity)
    p = plant.params
    res = RunResult.from_outcome(
        out, limp_at_end=driver.limped, peak_tau_nm=plant.peak_tau_motor_nm, cap_nm=cap, speed_rad_s=aj.speed_rad_s,
        abort_span_rad=span,
    )  # fmt: skip
    if out.ok and p.stop_lower_rad is not None and p.stop_upper_rad is not None:
        ideal = 0.5 * (p.stop_lower_rad + p.stop_upper_rad) - 0.5 * (j.lower + j.upper)
        res.zero_err_deg = math.degrees(out.stops.offset_rad - ideal)
        res.span_err_deg = math.degrees(out.stops.span_rad - (p.stop_upper_rad - p.stop_lower_rad))
    return res


@dataclass
class ScenarioStats:
    """Numbers of one scenario over its seeds."""

    robot: str
    spec: ScenarioSpec
    runs: list[RunResult] = field(default_factory=list)

    def _vals(self, attr: str) -> list[float]:
        return [getattr(r, attr) for r in self.runs if math.isfinite(getattr(r, attr))]

    def summary(self) -> dict[str, Any]:
        z, s = self._vals("zero_err_deg"), self._vals("span_err_deg")
        codes: dict[str, int] = {}
        for r in self.runs:
            codes[r.code] = codes.get(r.code, 0) + 1
        # repeatability: σ of the zero error per joint over its seeds, the largest joint
        per_joint: dict[str, list[float]] = {}
        for r in self.runs:
            if math.isfinite(r.zero_err_deg):
                per_joint.setdefault(r.joint, []).append(r.zero_err_deg)
        sigma = max((statistics.pstdev(v) for v in per_joint.values() if len(v) > 1), default=math.nan)
        aborts = [(r.abort_time_s, r.abort_bound_s) for r in self.runs if math.isfinite(r.abort_time_s)]
        want = self.spec.confirmed_by
        return {
            "n": len(self.runs),
            "codes": codes,
            "confirmed": sum(want in r.tests for r in self.runs) if want else math.nan,
            "zero_max_deg": max((abs(v) for v in z), default=math.nan),
            "zero_mean_deg": statistics.fmean(z) if z else math.nan,
            "span_max_deg": max((abs(v) for v in s), default=math.nan),
            "span_mean_deg": statistics.fmean(s) if s else math.nan,
            "sigma_deg": sigma,
            "abort_max_over_bound_s": max((t - b for t, b in aborts), default=math.nan),
            "peak_over_cap": max(self._vals("peak_over_cap"), default=math.nan),
            "limp_after_fail": all(r.limp_at_end for r in self.runs if r.code != "ok"),
        }

    def problems(self) -> list[str]:
        """What misses the acceptance (empty: passes)."""
        return acceptance_problems(self.summary(), self.spec)


def acceptance_problems(s: dict[str, Any], e: ScenarioSpec) -> list[str]:
    """What a scenario's summary (``n``, ``codes``, worst errors, aborts, peak torque, limp) misses of the
    acceptance ``e`` expects (empty: passes); the Robstride and the servo benchmarks judge alike."""
    out: list[str] = []
    n = s["n"]
    if e.expect == "accurate":
        if s["codes"].get("ok", 0) != n:
            out.append(f"not every run found both stops: {s['codes']}")
        if not s["zero_max_deg"] <= e.zero_tol_deg:
            out.append(f"zero error {s['zero_max_deg']:.3f}° > {e.zero_tol_deg}°")
        if not s["span_max_deg"] <= e.span_tol_deg:
            out.append(f"span error {s['span_max_deg']:.3f}° > {e.span_tol_deg}°")
        if math.isfinite(s["sigma_deg"]) and s["sigma_deg"] > THRESHOLDS["sigma_deg"]:
            out.append(f"σ {s['sigma_deg']:.3f}° > {THRESHOLDS['sigma_deg']}°")
        if e.confirmed_by and s["confirmed"] != s["codes"].get("ok", 0):
            out.append(f"only {s['confirmed']} runs confirmed a stop by {e.confirmed_by}")
    elif e.expect == "abort":
        if s["codes"].get("missing_stop", 0) + s["codes"].get("timeout", 0) != n:
            out.append(f"not every run aborted: {s['codes']}")
        if not s["abort_max_over_bound_s"] <= THRESHOLDS["abort_margin_s"]:
            out.append(f"abort {s['abort_max_over_bound_s']:.2f} s after the travel bound")
    elif s["codes"].get("span_mismatch", 0) != n:
        out.append(f"not every run reported a span mismatch: {s['codes']}")
    if not s["peak_over_cap"] <= THRESHOLDS["peak_over_cap"]:
        out.append(f"peak torque {s['peak_over_cap']:.3f}× the cap")
    if not s["limp_after_fail"]:
        out.append("a failed joint was not left limp")
    return out


def run_scenario(robot_name: str, spec: ScenarioSpec, seeds: Sequence[int]) -> ScenarioStats:
    """Run ``spec`` for every seed on robot ``lite`` or ``so101``."""
    robot = _lite() if robot_name == "lite" else SO101
    st = ScenarioStats(robot_name, spec)
    for seed in seeds:
        st.runs.append(run_one(robot, spec, seed))
    return st


def robot_total_time(robot_name: str, seed: int = 0) -> float:
    """Simulated time of a whole clean robot, joint after joint (sum of the per-joint times)."""
    robot = _lite() if robot_name == "lite" else SO101
    spec = ScenarioSpec("clean", Scenario(), stiffness=600.0)
    return sum(run_one(robot, spec, seed * len(robot) + i).time_s for i in range(len(robot)))


def print_table_header(*, wall: bool = False) -> None:
    """The head of the acceptance table (one row per scenario: :func:`print_table_row`; ``wall``: a wall-time
    column)."""
    print(
        f"{'scenario':18s} {'codes':34s} {'|zero|max':>9s} {'|span|max':>9s} {'σ zero':>7s} "
        f"{'abort-bound':>11s} {'peak/cap':>8s} {'re-read':>7s}{'  wall s' if wall else ''}  verdict",
        flush=True,
    )


def print_table_row(st: ScenarioStats, wall_s: float | None = None) -> int:
    """Print one scenario's row of the acceptance table (with its wall time when given); 1 when it fails."""
    s, probs = st.summary(), st.problems()
    codes = ",".join(f"{k}:{v}" for k, v in sorted(s["codes"].items()))

    def f(x: float, nd: int = 3) -> str:
        return "-" if not math.isfinite(x) else f"{x:.{nd}f}"

    print(
        f"{st.spec.name:18s} {codes:34s} {f(s['zero_max_deg']):>9s} {f(s['span_max_deg']):>9s} "
        f"{f(s['sigma_deg']):>7s} {f(s['abort_max_over_bound_s'], 2):>11s} {f(s['peak_over_cap']):>8s} "
        f"{f(s['confirmed'], 0):>7s}"
        f"{'' if wall_s is None else f'{wall_s:8.0f}'}  "
        f"{'PASS' if not probs else 'FAIL: ' + '; '.join(probs)}",
        flush=True,
    )
    return int(bool(probs))


def robot_seeds(robot_name: str) -> tuple[range, str]:
    """The seeds to run per scenario for ``robot_name`` and how they were chosen (for the table's title).

    ``AUTOCAL_SEEDS_PER_JOINT=N`` gives every joint N runs (N × joints seeds, seed → joint cycling);
    otherwise ``AUTOCAL_SEEDS`` (default 100) seeds per scenario, shared out over the joints.
    """
    per_joint = os.environ.get("AUTOCAL_SEEDS_PER_JOINT")
    if per_joint:
        n_joints = len(_lite() if robot_name == "lite" else SO101)
        n = int(per_joint)
        return range(n * n_joints), f"{n} seeded runs per joint and scenario ({n_joints} joints)"
    n = int(os.environ.get("AUTOCAL_SEEDS", "100"))
    return range(n), f"{n} seeded runs per scenario (seed → joint, cycling)"


def main() -> None:
    robots = [r for r in os.environ.get("AUTOCAL_ROBOTS", "lite,so101").split(",") if r]
    wanted = [w for w in os.environ.get("AUTOCAL_SCENARIOS", "").split(",") if w]
    failures = 0
    for robot in robots:
        seeds, how = robot_seeds(robot)
        print(f"-- {robot}: {how} --")
        print_table_header()
        for spec in SCENARIOS:
            if not wanted or spec.name in wanted:
                failures += print_table_row(run_scenario(robot, spec, seeds))
        total = robot_total_time(robot)
        limit = THRESHOLDS[f"{robot}_total_s"]
        print(
            f"whole {robot}: {total:.1f} s simulated (limit {limit:.0f} s) "
            f"{'PASS' if total < limit else 'FAIL'}\n",
            flush=True,
        )
        failures += total >= limit
    print(f"autocal acceptance: {'PASS' if not failures else f'{failures} FAIL'}")
