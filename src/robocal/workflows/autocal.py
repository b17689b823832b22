"""Automatic hard-stop calibration: drive each joint into its stops, safely, and compute the zeros.

The search itself is :class:`robocal.core.stop_search.StopSearch` (pure, backend-neutral); this module runs it on
:class:`JointDriver` objects — a Robstride motor over python-can (:class:`RobstrideJointDriver`), a Feetech or
Dynamixel servo (:mod:`robocal.workflows.autocal_servo`) — in the order and with the torque, speed and poses of a
robot profile's ``auto_calibration`` section (:class:`robocal.core.profile_auto.AutoSection`).

Safety (docs/auto_calibration.md): every search has travel and time bounds; any exception (Ctrl-C included)
makes every driver go limp at once (:func:`limp_all`) before it propagates; nothing is written here (the callers
write files only once every joint passed, or with ``partial``).
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Iterator, Mapping, Sequence
from contextlib import contextmanager, suppress
from dataclasses import dataclass, field
from typing import Any, Protocol

from ..core.profile_auto import AutoJoint, AutoSection
from ..core.stop_search import Command, JointStops, Sample, SearchConfig, StopResult, StopSearch, joint_zero
from ..errors import CalibError, CalibTimeoutError, DeviceError, UsageError

__all__ = [
    "AutoCalAbortedError",
    "AutoCalFailedError",
    "AutoCalResult",
    "AutoView",
    "Clock",
    "JointDriver",
    "JointOutcome",
    "MonotonicClock",
    "RobstrideJointDriver",
    "calibrate_joint",
    "limp_all",
    "run_autocal",
    "select_joints",
]


class AutoCalAbortedError(CalibError):
    """The auto-calibration was interrupted or hit a fault: every motor was made limp, nothing was written."""

    exit_code = 3


class AutoCalFailedError(CalibError):
    """One or more joints failed (missing stop, snag, span mismatch, ...); nothing was written.

    Attributes:
        result: The run's result (the passing joints' zeros are in it).
    """

    exit_code = 3

    def __init__(self, message: str, result: AutoCalResult) -> None:
        super().__init__(message)
        self.result = result


class Clock(Protocol):
    """Where a driver takes its time from (wall clock on hardware, a simulated clock in a simulator)."""

    def now(self) -> float:
        """Seconds (monotonic)."""
        ...

    def sleep(self, dt_s: float) -> Any:
        """Let ``dt_s`` seconds pass."""
        ...


class MonotonicClock:
    """The wall clock (``time.monotonic``/``time.sleep``), for real hardware."""

    def now(self) -> float:
        """Seconds since an arbitrary origin."""
        return time.monotonic()

    def sleep(self, dt_s: float) -> None:
        """Sleep ``dt_s`` seconds (no-op for ≤ 0)."""
        if dt_s > 0:
            time.sleep(dt_s)


class JointDriver(Protocol):
    """One joint as the stop search sees it (joint frame ``s = direction·raw``, rad; N·m)."""

    name: str

    def read(self) -> Sample:
        """Read the joint without changing what the motor does."""
        ...

    def execute(self, cmd: Command) -> Sample:
        """Carry out ``cmd`` for one control period; return the reading at its end."""
        ...

    def limp(self) -> None:
        """Torque off now (must not raise)."""
        ...


class AutoView(Protocol):
    """A live view of the run."""

    def joint_start(self, name: str, cap_nm: float, speed_rad_s: float) -> None:
        """A joint's search begins."""
        ...

    def sample(self, name: str, phase: str, side: str, sample: Sample) -> None:
        """One reading of the joint being searched."""
        ...

    def joint_done(self, outcome: JointOutcome) -> None:
        """A joint finished (passed or failed)."""
        ...


@dataclass(frozen=True)
class JointOutcome:
    """One joint's auto-calibration.

    Attributes:
        stops: The combined stops, zero and verdict (:class:`JointStops`).
        cap_nm: Torque cap used.
        speed_rad_s: Approach speed used.
        time_s: Time the joint took (search, back-off, parking).
    """

    stops: JointStops
    cap_nm: float
    speed_rad_s: float
    time_s: float

    @property
    def name(self) -> str:
        """Joint name."""
        return self.stops.name

    @property
    def ok(self) -> bool:
        """Whether the joint passed."""
        return self.stops.ok

    def to_report(self) -> dict[str, Any]:
        """The joint's report entry."""
        d = self.stops.to_report()
        d.update(cap_nm=round(self.cap_nm, 4), speed_deg_s=round(math.degrees(self.speed_rad_s), 3))
        d["time_s"] = round(self.time_s, 3)
        return d


@dataclass(frozen=True)
class AutoCalResult:
    """A whole run: the outcome of every searched joint in search order.

    Attributes:
        joints: Outcomes in order.
        total_time_s: Time of the whole run (driver clock).
        interrupted: The run was interrupted (the joints after the interruption are missing).
    """

    joints: tuple[JointOutcome, ...]
    total_time_s: float
    interrupted: bool = False

    def __getitem__(self, name: str) -> JointOutcome:
        for j in self.joints:
            if j.name == name:
                return j
        raise KeyError(name)

    @property
    def failed(self) -> tuple[JointOutcome, ...]:
        """Joints that failed."""
        return tuple(j for j in self.joints if not j.ok)

    @property
    def offsets_rad(self) -> dict[str, float]:
        """Joint-frame position offsets (``q_joint = s − offset``) of the passing joints."""
        return {j.name: j.stops.offset_rad for j in self.joints if j.ok}

    def failure_summary(self) -> str:
        """One line naming each failed joint with its code and reason."""
        return "; ".join(f"{j.name}: {j.stops.code} ({j.stops.reason})" for j in self.failed)

    def to_report(self) -> dict[str, Any]:
        """The ``auto`` part of a sweep report."""
        return {
            "total_time_s": round(self.total_time_s, 3),
            "interrupted": self.interrupted,
            "joints": {j.name: j.to_report() for j in self.joints},
        }


# ------------------------------------------------------------------------------------------------ limp
def limp_all(drivers: Mapping[str, JointDriver] | Sequence[JointDriver]) -> None:
    """Torque off every driver (errors ignored: each motor gets its chance)."""
    items = drivers.values() if isinstance(drivers, Mapping) else drivers
    for d in items:
        with suppress(Exception):  # a limp must reach every motor
            d.limp()


@contextmanager
def limp_on_error(drivers: Mapping[str, JointDriver]) -> Iterator[None]:
    """Any exception inside (Ctrl-C too): every driver goes limp, then the exception propagates."""
    try:
        yield
    except BaseException:
        limp_all(drivers)
        raise


# ------------------------------------------------------------------------------------------------ one joint
def _config(
    joint: AutoJoint,
    section: AutoSection,
    *,
    max_travel_rad: float,
    max_lag_rad: float,
    gravity: Callable[[float], float] | None,
) -> SearchConfig:
    speed = joint.speed_rad_s
    return SearchConfig(
        speed_rad_s=speed,
        torque_cap_nm=joint.torque_cap_nm,
        max_travel_rad=max_travel_rad,
        max_time_s=max_travel_rad / speed
        + 2.0
        + 2 * section.dwell_s
        + 0.6
        + math.radians(section.backoff_deg) / speed,
        max_lag_rad=max_lag_rad,
        dwell_s=section.dwell_s,
        backoff_rad=math.radians(section.backoff_deg),
        second_touch=section.second_touch,
        gravity_nm=gravity,
    )


def run_search(
    driver: JointDriver, search: StopSearch, view: AutoView | None = None, side: str = ""
) -> StopResult:
    """Run one stop search on ``driver`` to its end; a failed search leaves the joint limp."""
    cmd = search.start(driver.read())
    while not search.done:
        s = driver.execute(cmd)
        if view is not None:
            view.sample(driver.name, search.phase, side, s)
        cmd = search.step(s)
    if cmd.action == "limp":
        driver.limp()
    else:
        driver.execute(cmd)
    return search.result


def move_to(
    driver: JointDriver,
    target_rad: float,
    speed_rad_s: float,
    cap_nm: float,
    max_lag_rad: float,
    tol_rad: float = math.radians(1.0),
    timeout_s: float | None = None,
    stall_s: float | None = None,
) -> tuple[Sample, bool]:
    """Ramp the joint to ``target_rad`` (torque limited: the target never leads by more than ``max_lag_rad``).

    Args:
        driver: The joint.
        target_rad: Where to go (driver frame).
        speed_rad_s: Ramp speed.
        cap_nm: Torque limit of the move.
        max_lag_rad: The largest lead of the target.
        tol_rad: Arrival tolerance.
        timeout_s: Time bound (default: distance/speed + 3 s).
        stall_s: When given, a joint held back (target leading by ≥ 90 % of ``max_lag_rad`` and slower than
            10 % of the speed) for this long ends the move early: returns ``(reading, True)``.

    Returns:
        The last reading and whether the move ended on a stall.

    Raises:
        AutoCalAbortedError: The joint does not get there in time (blocked, without ``stall_s``).
    """
    s = driver.read()
    if not s.ok:
        raise CalibTimeoutError(f"joint {driver.name}: no reply")
    t0 = s.t_s
    ref = s.q_rad
    distance = abs(target_rad - ref)
    limit = timeout_s if timeout_s is not None else distance / speed_rad_s + 3.0
    last = s.t_s
    stalled_since: float | None = None
    while True:
        dt = max(s.t_s - last, 0.0)
        last = s.t_s
        step = speed_rad_s * dt
        ref = target_rad if abs(target_rad - ref) <= step else ref + math.copysign(step, target_rad - ref)
        if s.ok and math.isfinite(s.q_rad):
            ref = min(max(ref, s.q_rad - max_lag_rad), s.q_rad + max_lag_rad)
        at_end = ref == target_rad
        v_ff = 0.0 if at_end else math.copysign(speed_rad_s, target_rad - ref)
        s = driver.execute(Command("drive", ref, v_ff, cap_nm))
        if s.ok and at_end and abs(s.q_rad - target_rad) <= tol_rad:
            return s, False
        if stall_s is not None and s.ok:
            v = s.v_rad_s if math.isfinite(s.v_rad_s) else 0.0
            held = abs(ref - s.q_rad) >= 0.9 * max_lag_rad and abs(v) < 0.1 * speed_rad_s
            if held:
                stalled_since = s.t_s if stalled_since is None else stalled_since
                if s.t_s - stalled_since >= stall_s:
                    return s, True
            else:
                stalled_since = None
        if s.t_s - t0 > limit:
            q = f"{math.degrees(s.q_rad):.1f}°" if s.ok else "unknown"
            raise AutoCalAbortedError(
                f"joint {driver.name}: could not reach {math.degrees(target_rad):.1f}° within {limit:.1f} s "
                f"(at {q}): blocked?"
            )


TRANSIT_FACTOR = 5.0
"""Moves that are not searches (to near the second stop, to the park angle) go this much faster than the search."""
TRANSIT_MAX_RAD_S = math.radians(120.0)
"""... but never faster than this."""


def calibrate_joint(
    driver: JointDriver,
    joint: AutoJoint,
    section: AutoSection,
    expected_lower_rad: float | None,
    expected_upper_rad: float | None,
    *,
    max_lag_rad: float,
    gravity: Callable[[float], float] | None = None,
    view: AutoView | None = None,
) -> JointOutcome:
    """Find the stop(s) of one joint, compute its zero, park it.

    Two-sided: the lower stop first (travel bound: the expected span + tolerance, since the joint may start
    anywhere), then the upper one (bound: span − back-off + tolerance), then the joint parks at ``park_deg``
    (default: the middle of the measured stops). One-sided: only that stop (travel bound: the expected span +
    tolerance when both expected angles are known, else one turn).

    A failed search leaves the joint limp; the outcome carries its code and reason.
    """
    t0 = driver.read().t_s
    cap = joint.torque_cap_nm
    tol = math.radians(joint.tolerance_deg)
    span = (
        expected_upper_rad - expected_lower_rad
        if expected_lower_rad is not None and expected_upper_rad is not None
        else 2 * math.pi
    )
    if view is not None:
        view.joint_start(joint.name, cap, joint.speed_rad_s)
    lower: StopResult | None = None
    upper: StopResult | None = None
    first_dir = -1 if joint.stops in ("both", "lower") else 1
    cfg = _config(joint, section, max_travel_rad=span + tol, max_lag_rad=max_lag_rad, gravity=gravity)
    first = run_search(driver, StopSearch(first_dir, cfg), view, "lower" if first_dir < 0 else "upper")
    if first_dir < 0:
        lower = first
    else:
        upper = first
    transit = min(TRANSIT_FACTOR * joint.speed_rad_s, TRANSIT_MAX_RAD_S)
    if first.ok and joint.stops == "both":
        backoff = math.radians(section.backoff_deg)
        start = driver.read()
        travel = span - backoff + tol
        # fast to 2·tol short of where the upper stop is expected; a stall on the way is an early stop
        near = first.q_stop_rad + span - 2 * tol
        if start.ok and near - start.q_rad > math.radians(10.0):
            s, stalled = move_to(driver, near, transit, cap, max_lag_rad, stall_s=section.dwell_s)
            if stalled:
                upper = StopResult(
                    1,
                    "ok",
                    q_stop_rad=s.q_rad,
                    q_pressed_rad=s.q_rad,
                    torque_nm=s.torque_nm,
                    test="transit-stall",
                    t_detect_s=s.t_s - start.t_s,
                    duration_s=s.t_s - start.t_s,
                    travel_rad=abs(s.q_rad - start.q_rad),
                )
            else:
                travel = first.q_stop_rad + span + tol - s.q_rad
        if upper is None:
            cfg2 = _config(joint, section, max_travel_rad=travel, max_lag_rad=max_lag_rad, gravity=gravity)
            upper = run_search(driver, StopSearch(1, cfg2), view, "upper")
    stops = joint_zero(
        joint.name,
        lower,
        upper,
        expected_lower_rad,
        expected_upper_rad,
        span_tol_rad=math.radians(section.span_tolerance_deg),
    )
    if stops.ok:
        park = _park_target(joint, stops, expected_lower_rad, expected_upper_rad)
        try:
            move_to(driver, park, transit, cap, max_lag_rad)
        except AutoCalAbortedError as exc:
            driver.limp()
            stops = JointStops(
                joint.name,
                "blocked",
                str(exc),
                lower,
                upper,
                math.nan,
                stops.span_rad,
                stops.expected_span_rad,
            )
    else:
        driver.limp()
    outcome = JointOutcome(stops, cap, joint.speed_rad_s, driver.read().t_s - t0)
    if view is not None:
        view.joint_done(outcome)
    return outcome


def _park_target(joint: AutoJoint, stops: JointStops, lo: float | None, hi: float | None) -> float:
    """Where the joint parks, in the driver's frame ``s`` (the zero is known now: ``s = q + offset``)."""
    if joint.park_deg is not None:
        return math.radians(joint.park_deg) + stops.offset_rad
    if stops.lower is not None and stops.upper is not None:
        return 0.5 * (stops.lower.q_stop_rad + stops.upper.q_stop_rad)
    res = stops.lower if stops.lower is not None else stops.upper
    assert res is not None
    return res.q_stop_rad - res.direction * math.radians(15.0)  # 15° off the one stop


# ------------------------------------------------------------------------------------------------ a robot
def select_joints(section: AutoSection, joints: Sequence[str] | None) -> tuple[AutoJoint, ...]:
    """The profile's joints in search order, restricted to ``joints`` (``--joints``) when given.

    Raises:
        UsageError: ``joints`` names a joint the profile's auto_calibration section lacks.
    """
    if not joints:
        return section.joints
    unknown = [n for n in joints if section.joint(n) is None]
    if unknown:
        raise UsageError(
            f"--joints: no auto-calibration entry for {', '.join(unknown)}; joints: {', '.join(section.joint_names)}"
        )
    wanted = set(joints)
    return tuple(j for j in section.joints if j.name in wanted)


@dataclass
class _Run:
    offsets: dict[str, float] = field(default_factory=dict)


def run_autocal(
    drivers: Mapping[str, JointDriver],
    section: AutoSection,
    limits: Mapping[str, tuple[float | None, float | None]],
    *,
    joints: Sequence[str] | None = None,
    max_lag_rad: Mapping[str, float] | float = math.radians(3.0),
    gravity: Mapping[str, Callable[[float], float]] | None = None,
    view: AutoView | None = None,
    clock: Clock | None = None,
) -> AutoCalResult:
    """Auto-calibrate the joints of ``section`` (or the ``joints`` subset) in order.

    Before each joint, the joints already calibrated that its ``pose`` names move to those angles (their zero
    is known by then). A joint that fails is left limp and the run goes on with the next one. Any exception —
    Ctrl-C, a lost bus — makes every driver limp before it propagates (as :class:`AutoCalAbortedError` for a
    device error, unchanged for ``KeyboardInterrupt``).

    Args:
        drivers: Joint name → driver (every selected joint needs one).
        section: The profile's auto-calibration section.
        limits: Joint → URDF (lower, upper) limits (rad), the default expected stop angles.
        joints: Subset to calibrate (``--joints``), in the profile's order.
        max_lag_rad: Per joint or for all: the most the position target may lead the joint (the drive's
            ``cap/kp``).
        gravity: Joint → gravity torque model ``τ_g(s)`` in the driver's frame, for the correction.
        view: Live view.
        clock: Clock for the total time (default: the first driver's readings).

    Raises:
        UsageError: A selected joint has no driver.
        AutoCalAbortedError: A device fault (every motor is limp).
    """
    order = select_joints(section, joints)
    lacking = [j.name for j in order if j.name not in drivers]
    if lacking:
        raise UsageError(f"no motor for joint(s) {', '.join(lacking)}")
    run = _Run()
    outcomes: list[JointOutcome] = []
    t_start = clock.now() if clock is not None else drivers[order[0].name].read().t_s
    with limp_on_error(drivers):
        try:
            for joint in order:
                for other, angle_deg in joint.pose:
                    if other in run.offsets and other in drivers:
                        move_to(
                            drivers[other],
                            math.radians(angle_deg) + run.offsets[other],
                            section.joint(other).speed_rad_s * TRANSIT_FACTOR,  # type: ignore[union-attr]
                            section.joint(other).torque_cap_nm,  # type: ignore[union-attr]
                            _lag(max_lag_rad, other),
                        )
                lo, hi = joint.expected_rad(*limits.get(joint.name, (None, None)))
                outcome = calibrate_joint(
                    drivers[joint.name],
                    joint,
                    section,
                    lo,
                    hi,
                    max_lag_rad=_lag(max_lag_rad, joint.name),
                    gravity=None if gravity is None else gravity.get(joint.name),
                    view=view,
                )
                outcomes.append(outcome)
                if outcome.ok:
                    run.offsets[joint.name] = outcome.stops.offset_rad
        except (DeviceError, AutoCalAbortedError) as exc:
            limp_all(drivers)
            raise AutoCalAbortedError(f"auto-calibration aborted, every motor limp: {exc}") from None
    t_end = clock.now() if clock is not None else drivers[order[-1].name].read().t_s
    return AutoCalResult(tuple(outcomes), t_end - t_start)


def _lag(value: Mapping[str, float] | float, name: str) -> float:
    return float(value[name]) if isinstance(value, Mapping) else float(value)


# ------------------------------------------------------------------------------------------------ Robstride
ROBSTRIDE_OVERCURRENT_BIT = 1 << 1
"""Type-2 fault bit 17 (bit 1 of the 6 fault bits): over-current — an overload, suspect evidence only."""
ROBSTRIDE_FATAL_BITS = (1 << 0) | (1 << 2) | (1 << 3) | (1 << 4)
"""Under-voltage, over-temperature, encoder and Hall faults end the run."""


class RobstrideJointDriver:
    """A Robstride motor driven with MIT frames (type 1) through :class:`~robocal.backends.robstride.RobstrideBus`.

    ``drive``/``hold``: position target with ``kp = cap / max_lag`` (scaled down for a lower limit) and a small
    ``kd``, feed-forward velocity, no feed-forward torque, so ``|τ| ≤ kp·max_lag + kd·|v_ref − v|`` (the cap plus
    a little damping). ``push``: ``kp = 0``, ``τ_ff = ±limit``, damping ``kd``. ``limp``: MIT ``(0, 0, 0, 0, 0)``
    then type 4 (stop). ``reread``: type 4 stop with fault clear, type 3 enable, a zero-torque MIT read. Angles
    are in the joint's identity frame ``s = direction·raw``. Nothing is ever written to the motor's flash or
    parameters.

    Args:
        bus: The bus the motor is on.
        name: Joint (motor) name on that bus.
        direction: URDF direction ±1.
        cap_nm: Torque cap the gains are computed for.
        max_lag_rad: The largest lead of the target (``kp = cap/max_lag``).
        clock: Time source; :meth:`execute` lets ``period_s`` pass per command.
        period_s: Control period.
        kd: Damping gain, N·m·s/rad (default ``0.05·cap`` per rad/s: damping adds ≤ 5 % of the cap at 1 rad/s).
    """

    def __init__(
        self,
        bus: Any,
        name: str,
        direction: int,
        cap_nm: float,
        max_lag_rad: float,
        clock: Clock,
        *,
        period_s: float = 0.01,
        kd: float | None = None,
    ) -> None:
        self.bus = bus
        self.name = name
        self.direction = int(direction)
        self.cap_nm = float(cap_nm)
        self.kp = cap_nm / max_lag_rad
        self.kd = 0.05 * cap_nm if kd is None else kd
        self.clock = clock
        self.period_s = period_s
        self.enabled = False
        self._last: tuple[float, float, float, float, float] = (0.0, 0.0, 0.0, self.kd, 0.0)
        self._q = math.nan

    def _sample(self, fb: Any) -> Sample:
        d = self.direction
        if fb.faults & ROBSTRIDE_FATAL_BITS:
            raise DeviceError(f"joint {self.name}: motor fault bits {fb.faults:#04x}")
        s = Sample(
            self.clock.now(),
            d * fb.position_rad,
            d * fb.velocity_rad_s,
            d * fb.torque_nm,
            True,
            bool(fb.faults & ROBSTRIDE_OVERCURRENT_BIT),
        )
        self._q = s.q_rad
        return s

    def _mit(self, cmd: tuple[float, float, float, float, float]) -> Sample:
        d = self.direction
        p, v, kp, kd, t = cmd
        t_send = self.clock.now()
        try:
            fb = self.bus.mit_command(self.name, d * p, d * v, kp, kd, d * t)
        except CalibTimeoutError:
            s = Sample(self.clock.now(), math.nan, ok=False)
        else:
            s = self._sample(fb)
        self.clock.sleep(self.period_s - (self.clock.now() - t_send))
        return s

    def _enable(self) -> Sample:
        try:
            fb = self.bus.enable(self.name)
        except CalibTimeoutError:
            return Sample(self.clock.now(), math.nan, ok=False)
        self.enabled = True
        s = self._sample(fb)
        self._last = (
            0.0,
            0.0,
            0.0,
            self.kd,
            0.0,
        )  # damping only until the first command: enabling never moves
        return s

    def read(self) -> Sample:
        """Read the joint, repeating the last command (enable first, with damping only, if needed)."""
        if not self.enabled:
            s = self._enable()
            if not s.ok:
                return s
        return self._mit(self._last)

    def execute(self, cmd: Command) -> Sample:
        """One MIT frame for ``cmd``; its feedback frame is the reading."""
        if cmd.action == "limp":
            self.limp()
            return Sample(self.clock.now(), self._q, ok=math.isfinite(self._q))
        if not self.enabled:
            s = self._enable()
            if not s.ok:
                return s
        if cmd.action == "reread":
            with suppress(CalibTimeoutError):
                self.bus.stop(self.name, clear_faults=True)
            self.enabled = False
            s = self._enable()
            if not s.ok:
                return s
            return self._mit(self._last)
        if cmd.action == "push":
            sign = 1.0 if not math.isfinite(self._q) or cmd.q_target_rad >= self._q else -1.0
            self._last = (0.0, 0.0, 0.0, self.kd, sign * cmd.torque_limit_nm)
        else:
            kp = self.kp * min(1.0, cmd.torque_limit_nm / self.cap_nm)
            self._last = (cmd.q_target_rad, cmd.v_target_rad_s, kp, self.kd, 0.0)
        return self._mit(self._last)

    def limp(self) -> None:
        """MIT zero torque, then type 4 stop (reset mode); never raises."""
        self._last = (0.0, 0.0, 0.0, 0.0, 0.0)
        with suppress(Exception):
            self.bus.mit_command(self.name, 0.0, 0.0, 0.0, 0.0, 0.0)
        with suppress(Exception):
            self.bus.stop(self.name)
        self.enabled = False
