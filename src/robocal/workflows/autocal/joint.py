"""One joint of the automatic hard-stop calibration: its moves and stop searches as steps, its outcome.

The drivers, clocks and results are in :mod:`robocal.workflows.autocal.model`. See
:mod:`robocal.workflows.autocal.job` (the robot-level run) and docs/auto_calibration.md.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Generator
from dataclasses import replace
from typing import Concatenate, ParamSpec, TypeVar

from ...backends import reply_timeout_floor_s
from ...core.profile_auto import AutoJoint, AutoSection
from ...core.stop_search import (
    EVIDENCE_GAP_S,
    Command,
    JointStops,
    SearchConfig,
    StopResult,
    StopSample,
    StopSearch,
    joint_zero,
)
from ...errors import CalibTimeoutError
from .model import (
    AutoCalAbortedError,
    AutoView,
    JointDriver,
    JointOutcome,
)

__all__ = [
    "PRESS_NET_FRACTION",
    "TRANSIT_FACTOR",
    "TRANSIT_MAX_RAD_S",
    "JointSteps",
    "calibrate_joint",
    "calibrate_joint_steps",
    "carried_out",
    "drive",
    "move_steps",
    "move_to",
    "press_fraction",
    "run_search",
    "search_steps",
]

_T = TypeVar("_T")
_P = ParamSpec("_P")

FRICTION_SETTLE_S = 0.5
"""A move that ends at rest short of its target, inside the drive's lag and below the cap (held by friction,
not by a stop), counts as arrived after this long."""

MOVE_OVERLOAD_CLEARS = 3
"""Overload latches :func:`move_steps` clears (``reread``) and moves on from before it gives up."""

JointSteps = Generator[Command, StopSample, _T]
"""One joint's moves as a generator: it yields the next :class:`Command` and receives the reading at the end of
the control period that carried it out (:meth:`JointDriver.execute`); its return value is the result. Run it on
one driver with :func:`drive`, or several in lockstep (:mod:`robocal.workflows.autocal.group`)."""


# ------------------------------------------------------------------------------------------------ one joint
def _config(
    joint: AutoJoint,
    section: AutoSection,
    *,
    max_travel_rad: float,
    max_lag_rad: float,
    gravity: Callable[[float], float] | None,
    press_fraction: float = 0.5,
    max_reading_gap_s: float | None = None,
) -> SearchConfig:
    speed = joint.speed_rad_s
    return SearchConfig(
        press_fraction=press_fraction,
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
        # a reading later than this after the one before is a fault (stop_search.py); a machine whose replies
        # may take longer ($ROBOCAL_REPLY_TIMEOUT_MS, a simulator in another process) gets twice that
        reply_timeout_s=reply_bound_s(),
        max_reading_gap_s=max_reading_gap_s,
    )


READ_TRIES = 20
"""At most this many reads in :func:`read_within`."""


def reply_bound_s() -> float:
    """How long a joint may go without a good reading before its search or move fails ``no_reply``, s.

    0.5 s; a machine whose replies may take longer (``$ROBOCAL_REPLY_TIMEOUT_MS``, a simulator in another process)
    gets twice that floor.
    """
    return max(0.5, 2.0 * reply_timeout_floor_s())


def read_within(driver: JointDriver, bound_s: float) -> StopSample:
    """A good reading of ``driver``, asked again while replies are lost for at most ``bound_s`` (its clock's time).

    On a busy host one reply can come later than the bus's wait (dropped by the next exchange): a single lost
    reading at the start of a search or a move is no reason to fail the joint (the fault soaks' "no position
    reading at the start of the search" with no fault injected). A device that stays silent for ``bound_s``
    still fails as before: the last (not ok) reading is returned.
    """
    s = driver.read()
    t0 = s.t_s
    for _ in range(READ_TRIES - 1):  # also bounded where a lost reply takes no time (a test's driver)
        if s.ok or not s.t_s - t0 < bound_s:
            break
        s = driver.read()
    return s


PRESS_NET_FRACTION = 0.1
"""The second press level leaves at least this fraction of the cap pushing into the stop against gravity."""


def press_fraction(
    cap_nm: float, gravity_joint: Callable[[float], float] | None, stop_rad: float | None, direction: int
) -> float:
    """The second press level (fraction of the cap) for a stop where gravity may pull the joint off it.

    The stiffness estimate needs the joint on the stop at both press levels. Where the joint-frame gravity model
    says gravity pulls the joint away from the stop (at its expected angle) by more than half the cap minus
    :data:`PRESS_NET_FRACTION` of it, the second level is raised so that this much still pushes (at most 0.9 of
    the cap); otherwise it is the usual half. E.g. the OpenArm's J1 at its −80° stop: 7.9 N·m of gravity pull,
    a 10 N·m cap → 0.89.
    """
    if gravity_joint is None or stop_rad is None or not cap_nm > 0:
        return 0.5
    away_nm = -direction * gravity_joint(stop_rad)
    return min(0.9, max(0.5, (away_nm + PRESS_NET_FRACTION * cap_nm) / cap_nm))


def drive(driver: JointDriver, steps: JointSteps[_T]) -> _T:
    """Carry out ``steps`` on ``driver``, one :meth:`JointDriver.execute` per command; the steps' result."""
    try:
        cmd = next(steps)
        while True:
            cmd = steps.send(driver.execute(cmd))
    except StopIteration as stop:
        return stop.value  # type: ignore[no-any-return]


def carried_out(
    steps: Callable[Concatenate[JointDriver, _P], JointSteps[_T]], name: str, doc: str = ""
) -> Callable[Concatenate[JointDriver, _P], _T]:
    """The function ``name`` that builds ``steps(driver, ...)`` and carries them out on ``driver`` (:func:`drive`).

    One signature serves a joint's steps (a generator, for lockstep runs) and its direct form; ``doc`` is its
    docstring (default: "``steps`` carried out on ``driver``").
    """

    def run(driver: JointDriver, /, *args: _P.args, **kwargs: _P.kwargs) -> _T:
        return drive(driver, steps(driver, *args, **kwargs))

    run.__name__ = run.__qualname__ = name
    run.__doc__ = doc or f":func:`{steps.__name__}` carried out on ``driver`` (see there)."
    return run


def search_steps(
    driver: JointDriver, search: StopSearch, view: AutoView | None = None, side: str = ""
) -> JointSteps[StopResult]:
    """One stop search on ``driver`` to its end, as steps; a failed search leaves the joint limp."""
    cmd = search.start(read_within(driver, search.config.reply_timeout_s))
    while not search.done:
        s = yield cmd
        if view is not None:
            view.sample(driver.name, search.phase, side, s)
        cmd = search.step(s)
    if cmd.action == "limp":
        driver.limp()
    else:
        yield cmd
    return search.result


run_search = carried_out(
    search_steps, "run_search", "Run one stop search on ``driver`` to its end; a failed search leaves the joint limp."
)


def move_steps(
    driver: JointDriver,
    target_rad: float,
    speed_rad_s: float,
    cap_nm: float,
    max_lag_rad: float,
    tol_rad: float = math.radians(1.0),
    timeout_s: float | None = None,
    stall_s: float | None = None,
) -> JointSteps[tuple[StopSample, bool]]:
    """Ramp the joint to ``target_rad`` (torque limited: the target never leads by more than ``max_lag_rad``).

    Args:
        driver: The joint.
        target_rad: Where to go (driver frame).
        speed_rad_s: Ramp speed.
        cap_nm: Torque limit of the move.
        max_lag_rad: The largest lead of the target.
        tol_rad: Arrival tolerance.
        timeout_s: Time bound (default: distance/speed + 3 s).
        stall_s: When given, a joint held back (target leading by ≥ 90 % of ``max_lag_rad``, or the ramp over
            and the joint more than ``tol_rad`` short of the target while pushing at ≥ 90 % of ``cap_nm``; and
            slower than 10 % of the speed) for this long ends the move early: returns ``(reading, True)``.

    A joint that comes to rest short of the target but within 90 % of ``max_lag_rad``, pushing with less than
    90 % of the cap (so a stop is not what holds it: breakaway friction is, e.g. a small move from rest on a
    sticky joint), counts as arrived after :data:`FRICTION_SETTLE_S`.

    Under CPU load the tests judge what the joint did with the target it had a whole control period to reach
    (the one sent before the last), and the dwells and the time bound count each reading's interval at most
    :data:`~robocal.core.stop_types.EVIDENCE_GAP_S`: a scheduling gap is neither a stall nor a blocked move
    (issue 26 item 4).

    A reading with the motor's overload flag (its protection latched and cut the torque, e.g. while accelerating
    at the cap) is suspect, never a stall: the latch is cleared (``reread``) and the move goes on from where the
    joint is, at most :data:`MOVE_OVERLOAD_CLEARS` times.

    Returns:
        The last reading and whether the move ended on a stall.

    Raises:
        AutoCalAbortedError: The joint does not get there in time (blocked, without ``stall_s``), or its
            overload protection latched more than :data:`MOVE_OVERLOAD_CLEARS` times.
    """
    s = read_within(driver, reply_bound_s())
    if not s.ok:
        raise CalibTimeoutError(f"joint {driver.name}: no reply")
    ref = sent = s.q_rad
    sense = 1.0 if target_rad >= ref else -1.0
    distance = abs(target_rad - ref)
    limit = timeout_s if timeout_s is not None else distance / speed_rad_s + 3.0
    last = s.t_s
    counted = 0.0  # time since the start, each reading's interval counted at most EVIDENCE_GAP_S
    stalled_since: float | None = None
    resting_since: float | None = None
    clears = 0
    while True:
        dt = max(s.t_s - last, 0.0)
        last = s.t_s
        counted += min(dt, EVIDENCE_GAP_S)
        step = speed_rad_s * dt
        ref = target_rad if abs(target_rad - ref) <= step else ref + math.copysign(step, target_rad - ref)
        clamped = False
        if s.ok and math.isfinite(s.q_rad):
            held = min(max(ref, s.q_rad - max_lag_rad), s.q_rad + max_lag_rad)
            clamped, ref = held != ref, held
        at_end = ref == target_rad
        # no velocity feed-forward while the target is held back: kd·(v_ref − v) would add to the capped kp·lag
        v_ff = 0.0 if at_end or clamped else math.copysign(speed_rad_s, target_rad - ref)
        given, sent = sent, ref  # the joint had a whole period to reach ``given``; ``ref`` was just sent
        s = yield Command("drive", ref, v_ff, cap_nm)
        now = counted + min(max(s.t_s - last, 0.0), EVIDENCE_GAP_S)  # this reading on the counted clock
        if s.ok and s.overload:
            clears += 1
            if clears > MOVE_OVERLOAD_CLEARS:
                raise AutoCalAbortedError(
                    f"joint {driver.name}: its overload protection latched {clears} times while moving to "
                    f"{math.degrees(target_rad):.1f}°"
                )
            s = yield Command("reread", ref, 0.0, cap_nm)
            if s.ok and math.isfinite(s.q_rad):
                ref = sent = s.q_rad
            stalled_since = resting_since = None
            continue
        if s.ok and at_end and abs(s.q_rad - target_rad) <= tol_rad:
            return s, False
        if s.ok and at_end and _held_by_friction(s, target_rad, 0.9 * max_lag_rad, 0.1 * speed_rad_s, 0.9 * cap_nm):
            resting_since = now if resting_since is None else resting_since
            if now - resting_since >= FRICTION_SETTLE_S:
                return s, False
        else:
            resting_since = None
        if stall_s is not None and s.ok:
            v = s.v_rad_s if math.isfinite(s.v_rad_s) else 0.0
            # held back by the lead, or (the ramp over) stuck short of the target while pushing at the cap
            pushing = math.isfinite(s.torque_nm) and abs(s.torque_nm) >= 0.9 * cap_nm
            short = at_end and abs(target_rad - s.q_rad) > tol_rad and pushing
            behind = sense * (given - s.q_rad)  # short of the target it had a period to reach (stop_search.py)
            held = (behind >= 0.9 * max_lag_rad or short) and abs(v) < 0.1 * speed_rad_s
            if held:
                stalled_since = now if stalled_since is None else stalled_since
                if now - stalled_since >= stall_s:
                    return s, True
            else:
                stalled_since = None
        if now > limit:
            q = f"{math.degrees(s.q_rad):.1f}°" if s.ok else "unknown"
            raise AutoCalAbortedError(
                f"joint {driver.name}: could not reach {math.degrees(target_rad):.1f}° within {limit:.1f} s "
                f"(at {q}): blocked?"
            )


def _held_by_friction(
    s: StopSample, target_rad: float, within_rad: float, slow_rad_s: float, below_nm: float
) -> bool:
    """At rest within ``within_rad`` of the target and pushing with less than ``below_nm`` (not against a stop)."""
    v = s.v_rad_s if math.isfinite(s.v_rad_s) else 0.0
    pushing = math.isfinite(s.torque_nm) and abs(s.torque_nm) >= below_nm
    return math.isfinite(s.q_rad) and abs(target_rad - s.q_rad) <= within_rad and abs(v) < slow_rad_s and not pushing


move_to = carried_out(move_steps, "move_to")

TRANSIT_FACTOR = 5.0
"""Moves that are not searches (to near the second stop, to the park angle) go this much faster than the search."""
TRANSIT_MAX_RAD_S = math.radians(120.0)
"""... but never faster than this."""


def _blocked_as_contact(result: StopResult) -> StopResult:
    """A search ``blocked`` at a known pressed position as a contact there (test ``blocked``), for the span check."""
    if result.code != "blocked" or not math.isfinite(result.q_pressed_rad):
        return result
    return replace(result, code="ok", reason="", q_stop_rad=result.q_pressed_rad, test="blocked")


def calibrate_joint_steps(
    driver: JointDriver,
    joint: AutoJoint,
    section: AutoSection,
    expected_rad: tuple[float | None, float | None],
    *,
    max_lag_rad: float,
    gravity: Callable[[float], float] | None = None,
    gravity_joint: Callable[[float], float] | None = None,
    view: AutoView | None = None,
) -> JointSteps[JointOutcome]:
    """Find the stop(s) of one joint, compute its zero, park it.

    Two-sided: the lower stop first (travel bound: the expected span + tolerance, since the joint may start
    anywhere), then the upper one (bound: span − back-off + tolerance), then the joint parks at ``park_deg``
    (default: the middle of the measured stops). One-sided: only that stop (travel bound: the expected span +
    tolerance when both expected angles are known, else one turn).

    Gravity: ``gravity`` is a model in the driver's frame ``s`` (a simulator's truth), used by the search at the
    press; ``gravity_joint`` one in the joint (URDF) frame (:func:`robocal.core.gravity.joint_gravity`), used by
    :func:`~robocal.core.stop_zero.joint_zero` once both stops are known. Give at most one.

    ``expected_rad`` is the (lower, upper) stop angle expected in the driver's frame, each None when unknown.
    A failed search leaves the joint limp; the outcome carries its code and reason.
    """
    expected_lower_rad, expected_upper_rad = expected_rad
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
    first_press = press_fraction(
        cap, gravity_joint, expected_lower_rad if first_dir < 0 else expected_upper_rad, first_dir
    )
    gap_s = getattr(driver, "READING_GAP_S", None)  # a driver whose motor's watchdog and read-back decide
    cfg = _config(
        joint, section, max_travel_rad=span + tol, max_lag_rad=max_lag_rad, gravity=gravity, press_fraction=first_press,
        max_reading_gap_s=gap_s,
    )
    first = yield from search_steps(
        driver, StopSearch(first_dir, cfg), view, "lower" if first_dir < 0 else "upper"
    )
    if joint.stops == "both":
        # blocked right after the start (the joint began beside an obstacle or a stop): a contact the span
        # check judges once the other side is found (a one-sided joint has no such check and stays failed)
        first = _blocked_as_contact(first)
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
            s, stalled = yield from move_steps(driver, near, transit, cap, max_lag_rad, stall_s=section.dwell_s)
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
            cfg2 = _config(
                joint,
                section,
                max_travel_rad=travel,
                max_lag_rad=max_lag_rad,
                gravity=gravity,
                press_fraction=press_fraction(cap, gravity_joint, expected_upper_rad, 1),
                max_reading_gap_s=gap_s,
            )
            upper = yield from search_steps(driver, StopSearch(1, cfg2), view, "upper")
            # blocked right after the transit: an early stop (obstacle, cable), judged by the span check
            upper = _blocked_as_contact(upper)
    stops = joint_zero(
        joint.name,
        lower,
        upper,
        expected_lower_rad,
        expected_upper_rad,
        span_tol_rad=math.radians(section.span_tolerance_deg),
        gravity=gravity_joint,
    )
    if stops.ok:
        park = _park_target(joint, stops, expected_lower_rad, expected_upper_rad)
        try:
            yield from move_steps(driver, park, transit, cap, max_lag_rad)
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
    clock = getattr(driver, "clock", None)  # a failed joint is limp: reading it would switch its motor on again
    outcome = JointOutcome(stops, cap, joint.speed_rad_s, (clock.now() if clock else driver.read().t_s) - t0)
    if view is not None:
        view.joint_done(outcome)
    return outcome


calibrate_joint = carried_out(calibrate_joint_steps, "calibrate_joint")


def _park_target(joint: AutoJoint, stops: JointStops, lo: float | None, hi: float | None) -> float:
    """Where the joint parks, in the driver's frame ``s`` (the zero is known now: ``s = q + offset``)."""
    if joint.park_deg is not None:
        return math.radians(joint.park_deg) + stops.offset_rad
    if stops.lower is not None and stops.upper is not None:
        return 0.5 * (stops.lower.q_stop_rad + stops.upper.q_stop_rad)
    res = stops.lower if stops.lower is not None else stops.upper
    assert res is not None
    return res.q_stop_rad - res.direction * math.radians(15.0)  # 15° off the one stop
