"""``robocal sweep --auto``: the Robstride joints find their own hard stops; same outputs as a hand sweep.

The joints are driven (MIT frames over python-can, :class:`~robocal.backends.robstride.joint_driver.RobstrideJointDriver`) in
the order of the robot profile's ``auto_calibration`` section; the measured contact surfaces take the place of
the hand sweep's sampled extremes in :func:`robocal.core.sweep.analyse_sweep` (so the bisection rule, the
diagnostics and the written file are exactly those of ``robocal sweep``), and the report gains an ``auto``
part: per joint q_stop−/q_stop+, span, estimated stiffness, detection torque, time and which test fired.

Nothing is written when a joint fails (missing stop, snag, span mismatch, ...) unless ``partial`` is given; an
interruption or a device fault leaves every motor limp and every file untouched.
"""

from __future__ import annotations

import contextlib
import json
import math
import os
from collections.abc import Callable, Iterator, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from ...backends.bus_transaction import transaction
from ...core.health.drift import JointDrift, offset_drift
from ...core.profile import RobotProfile
from ...core.sweep import analyse_sweep
from ...core.sweep_result import SweepResult
from ...core.vendors import drives_sweep_auto
from ...errors import UsageError
from ...fileio import atomic_write_bytes, atomic_write_text, backup_paths
from ...formats.profiles import resolve_profile
from ..motion.guard import MotionGuard
from .job import AutoCalRequest, run_autocal, select_joints
from .model import (
    AutoCalAbortedError,
    AutoCalFailedError,
    AutoCalResult,
    AutoView,
    Clock,
    ConfirmStart,
    JointCaps,
    JointDriver,
    MonotonicClock,
    joint_driver_class,
    limp_all,
)
from .zero import rezeroed_result, store_zeros, zeros_written

__all__ = ["AutoSweepOutcome", "SweepAutoRequest", "auto_sweep_result", "run_sweep_auto"]


@dataclass(frozen=True)
class AutoSweepOutcome:
    """What ``sweep --auto`` did.

    Attributes:
        auto: The stop searches.
        result: The sweep result the file was computed from.
        out: Calibration file written (None when nothing was written).
        fmt: Its format.
        report: Report written, or None.
        exit_code: 0 all joints passed, 1 written with ``partial`` although a joint failed or has a warning
            (``verify``: 1 when a joint drifted past the tolerance).
        drifts: ``verify``: per searched joint, how far the stored offset has drifted (nothing written).
    """

    auto: AutoCalResult
    result: SweepResult
    out: Path | None
    fmt: str
    report: Path | None
    exit_code: int
    drifts: tuple[JointDrift, ...] = ()


OpenDrivers = Callable[
    [Any, Sequence[Any], RobotProfile], tuple[dict[str, JointDriver], Clock, Callable[[], None]]
]
"""Opens the drivers for (source spec, joints, profile): returns drivers, clock and a close function."""


def auto_sweep_result(
    auto: AutoCalResult,
    joints: Sequence[Any],
    *,
    prior: Mapping[str, float] | None = None,
    span_tolerance_rad: float,
    expected: Mapping[str, tuple[float, float]],
    wraps: bool = True,
    zero_sta: int = 0,
) -> SweepResult:
    """The :class:`SweepResult` of an auto run: contact surfaces in place of the sampled extremes.

    A one-sided joint gets the other extreme placed ``upper − lower`` away, which makes the bisection rule give
    exactly the one-sided offset ``s_stop − stop``. Joints that failed or were not searched have no samples (the
    prior offset is kept, as for a joint not swept). ``wraps`` and ``zero_sta`` are the profile's
    ``position_wraps`` and the motors' power-on range (:func:`robocal.core.sweep.analyse_sweep`).
    """
    names = [j.name for j in joints]
    n = len(names)
    smin = np.full(n, np.nan)
    smax = np.full(n, np.nan)
    lower = np.array([expected[j.name][0] for j in joints], dtype=float)
    upper = np.array([expected[j.name][1] for j in joints], dtype=float)
    for i, name in enumerate(names):
        try:
            out = auto[name]
        except KeyError:
            continue
        st = out.stops
        if not st.ok:
            continue
        span = upper[i] - lower[i]
        lo = st.lower.q_stop_rad if st.lower is not None else None
        hi = st.upper.q_stop_rad if st.upper is not None else None
        if lo is None and hi is not None:
            lo = hi - span
        if hi is None and lo is not None:
            hi = lo + span
        assert lo is not None and hi is not None
        smin[i], smax[i] = lo, hi
    return analyse_sweep(
        names,
        [j.direction for j in joints],
        lower,
        upper,
        smin,
        smax,
        prior=prior,
        threshold_rad=0.0,
        span_tolerance_rad=span_tolerance_rad,
        wraps=wraps,
        zero_sta=zero_sta,
    )


@contextlib.contextmanager
def _all_or_nothing(paths: Sequence[Path]) -> Iterator[None]:
    """The report and the calibration are written together or not at all.

    Each file (through a symbolic link: its target) and its backups are read first; when anything interrupts
    the writes (Ctrl-C between the report and the calibration, a full disk on the second file), every one of
    them is put back as it was (a file that did not exist is removed) before the exception goes on.
    """
    saved: dict[Path, bytes | None] = {}
    for p in paths:
        target = Path(os.path.realpath(p))
        for f in (target, *backup_paths(target)):
            saved[f] = f.read_bytes() if f.is_file() else None
    try:
        yield
    except BaseException:
        for f, data in saved.items():
            with contextlib.suppress(OSError):
                if data is None:
                    if f.is_file():
                        f.unlink()
                elif not f.is_file() or f.read_bytes() != data:
                    atomic_write_bytes(f, data, backup=False)
        raise


def _open_robstride(
    spec: Any, joints: Sequence[Any], profile: RobotProfile
) -> tuple[dict[str, JointDriver], Clock, Callable[[], None]]:
    from ...backends.sources import open_source

    if spec.kind != "can":
        raise UsageError(f"--auto needs a live source (can:...) or sim:lite, not {spec.kind}")
    src = open_source(spec, joints)
    clock = MonotonicClock()
    drivers: dict[str, JointDriver] = {}
    auto = profile.auto
    assert auto is not None
    by_name = {j.name: j for j in joints}
    for bus in getattr(src, "buses", []):
        for name in bus.motors:
            aj = auto.joint(name)
            if aj is None:
                continue
            driver_cls = joint_driver_class("robstride")
            drivers[name] = driver_cls(
                bus, name, by_name[name].direction, aj.torque_cap_nm, driver_cls.MAX_LAG_RAD, clock
            )
    return drivers, clock, src.close


def _open_damiao(
    spec: Any, joints: Sequence[Any], profile: RobotProfile
) -> tuple[dict[str, JointDriver], Clock, Callable[[], None]]:
    from .damiao import open_damiao

    return open_damiao(spec, joints, profile)


_LIVE_OPENERS: dict[str, OpenDrivers] = {"robstride": _open_robstride, "damiao": _open_damiao}
"""Vendor (with ``sweep_auto``) → the opener of its live ``can:`` buses and joint drivers."""


@dataclass(frozen=True)
class _SimSpec:
    kind: str
    options: dict[str, str]
    text: str
    robot: str = "lite"


def _parse_auto_source(text: str) -> _SimSpec:
    """``sim:lite[?seed=N&missing=a,b&...]`` or ``sim:openarm[?...]`` (the options of :mod:`.sim`)."""
    from ...backends.sources.spec import parse_sim_options
    from .sim import SIM_FAULTS

    robot, _, query = text[len("sim:") :].partition("?")
    if robot not in ("lite", "openarm"):
        raise UsageError(
            f"--source {text!r}: --auto simulates sim:lite and sim:openarm only (LeRobot arms: lerobot calibrate "
            "--auto)"
        )
    valid = ("seed", *SIM_FAULTS, *(("zeroed", "zero_drift") if robot == "openarm" else ()))  # autocal/damiao.py
    opts = parse_sim_options(text, query, valid, joined=valid, valid_label="valid with --auto")
    return _SimSpec("sim", opts, text, robot)


@dataclass(frozen=True)
class SweepAutoRequest:
    """One ``robocal sweep --auto`` run: the robot, its source, what to write and which joints.

    The CLI builds it from ``robocal sweep``'s options; Python callers build it directly. The outputs, source
    and profile are checked by :func:`run_sweep_auto` before anything moves.

    Attributes:
        urdf_path: The robot's URDF (limits: the default expected stop angles).
        source: ``can:<interface>:<channel>[,...]`` or ``sim:lite[?...]``.
        out: Calibration file (updated in place when it exists; joints not searched keep their offsets).
        robot: Profile name or file (default: recognised from the URDF); it needs an ``auto_calibration`` section.
        joints: Subset to calibrate (``--joints``).
        report: JSON report to write (the sweep report plus an ``auto`` part).
        fmt: Output format (default as ``robocal sweep``).
        partial: Write the joints that passed even when others failed.
        write_zero: Once the stops are found, move each joint that passed to its 0 and store that position as
            its motor's zero (Damiao 0xFE, one flash write per motor; :mod:`.zero`); the file written then holds
            the offsets against the new zeros (≈ 0).
        gravity: Joint → gravity torque model in the driver's frame, for the correction (a simulator's truth).
            Without it, a URDF with ``<inertial>`` masses gives the correction
            (:func:`robocal.formats.urdf_gravity.gravity_model_if_any`).
        verify: Touch the stops again and compare the offsets they give with ``out``'s (which must exist);
            nothing is written (``report`` and ``partial`` are refused).
        tolerance_deg: ``verify``: drift above which a joint is flagged, degrees.
    """

    urdf_path: str | Path
    source: str
    out: str | Path
    robot: str | os.PathLike[str] | RobotProfile | None = None
    joints: Sequence[str] | None = None
    report: str | Path | None = None
    fmt: str | None = None
    partial: bool = False
    write_zero: bool = False
    gravity: Mapping[str, Callable[[float], float]] | None = None
    verify: bool = False
    tolerance_deg: float = 2.0

    def __post_init__(self) -> None:
        if not (math.isfinite(self.tolerance_deg) and self.tolerance_deg > 0):
            raise UsageError(
                f"--tolerance-deg: expected a positive number of degrees, got {self.tolerance_deg!r}"
            )
        if self.verify and (self.report is not None or self.partial):
            both = ", ".join(
                f for f, on in (("--report", self.report is not None), ("--partial", self.partial)) if on
            )
            raise UsageError(f"--verify writes nothing: {both} cannot be combined with it")


def run_sweep_auto(
    request: SweepAutoRequest,
    *,
    confirm_start: ConfirmStart | None = None,
    view: AutoView | None = None,
    open_drivers_fn: OpenDrivers | None = None,
) -> AutoSweepOutcome:
    """Auto-calibrate the Robstride joints of a robot and write the calibration like ``robocal sweep``.

    Args:
        request: The robot, source, outputs and joints (:class:`SweepAutoRequest`).
        confirm_start: Asked before anything moves; returning False ends the run with nothing moved.
        view: Live view.
        open_drivers_fn: Opens the drivers (default: Robstride buses from ``source``; the simulator passes its own).

    Raises:
        UsageError: Bad options, no auto section, not a Robstride robot, the start not confirmed.
        AutoCalFailedError: A joint failed and ``partial`` is not given (exit 3; nothing written).
        AutoCalAbortedError: A device fault (exit 3; every motor limp, nothing written).
        KeyboardInterrupt: Ctrl-C (every motor limp, nothing written; the CLI exits 130).
    """
    r = request
    urdf_path, source, out, robot, joints = r.urdf_path, r.source, r.out, r.robot, r.joints
    report, fmt, partial, gravity = r.report, r.fmt, r.partial, r.gravity
    from ...backends.sources import parse_source
    from ...formats.urdf import read_urdf
    from ...formats.urdf_gravity import gravity_model_if_any
    from ..sweep.job import existing_output, offsets_by_joint, write_sweep_files
    from ..sweep.joint_specs import joints_from_urdf
    from ..sweep.output import check_outputs, output_format

    out_path, report_path = check_outputs(out, report, fmt, urdf=urdf_path, robot=robot)
    spec = _parse_auto_source(source) if source.startswith("sim:") else parse_source(source)
    urdf = read_urdf(urdf_path)
    gravity_model = gravity_model_if_any(urdf_path) if gravity is None else None
    profile = resolve_profile(robot, urdf)
    if profile is None or profile.auto is None:
        who = "no robot profile is in effect" if profile is None else f"profile {profile.name} has none"
        raise UsageError(
            f"--auto needs a robot profile with an auto_calibration section; {who} (pass --robot NAME; "
            "docs/profiles.md)"
        )
    vendor = drives_sweep_auto(profile.actuator)
    if vendor is None:
        raise UsageError(
            f"--auto: robot {profile.name} has {profile.actuator} actuators; sweep --auto drives Robstride and "
            "Damiao motors (LeRobot arms: robocal lerobot calibrate --auto)"
        )
    sim_robot = getattr(spec, "robot", None) if spec.kind == "sim" else None
    if sim_robot is not None and sim_robot != vendor.sim_auto_robot:
        raise UsageError(
            f"--source {source!r}: robot {profile.name} has {vendor.name} actuators; simulate it with "
            f"sim:{vendor.sim_auto_robot}"
        )
    if fmt is None:
        fmt = output_format(out_path, profile)
    existing = existing_output(out_path, fmt, urdf, profile, verify=r.verify)
    if r.verify and r.write_zero:
        raise UsageError("--verify writes nothing: it does not go with --write-zero")
    if r.verify and existing is None:
        raise UsageError(f"--verify: no stored calibration at {out_path} to verify (calibrate first)")
    specs = joints_from_urdf(urdf, profile, existing)
    order = select_joints(profile.auto, joints, movable_only=True)
    known = {j.name for j in specs}
    lacking = [j.name for j in order if j.name not in known]
    if lacking:
        raise UsageError(
            f"--auto: joints {', '.join(lacking)} of profile {profile.name} are not in URDF {urdf.source}"
        )
    if r.verify and existing is not None:  # a joint with no stored offset: nothing to compare its stops with
        unstored = [j.name for j in order if j.searched and j.name not in set(existing.calibration.joint_names)]
        if unstored:
            raise UsageError(
                f"--verify: {out_path} stores no offset for {', '.join(unstored)}; calibrate those joints first or "
                "leave them out of --joints"
            )
    caps = JointCaps(order, vendor.host_loss)
    max_lag_rad = float(joint_driver_class(vendor.name).MAX_LAG_RAD)  # the vendor's driver says how far it leads
    if confirm_start is not None and not confirm_start(tuple(caps), caps):
        raise UsageError("not confirmed: nothing moved, nothing written")
    limits = {j.name: (j.lower, j.upper) for j in specs}
    opener = open_drivers_fn
    joint_gravity = None
    if sim_robot == "openarm" and gravity is None:
        from .damiao import openarm_gravity

        joint_gravity = openarm_gravity(profile)  # the simulator's truth stands in for the URDF's masses
    if opener is None:
        if spec.kind == "sim" and sim_robot == "openarm":
            from .damiao import sim_openarm_opener

            opener = sim_openarm_opener()
        elif spec.kind == "sim":
            from .sim import sim_opener

            opener = sim_opener()
        else:
            opener = _LIVE_OPENERS[vendor.name]
    drivers, clock, close = opener(spec, specs, profile)
    try:
        if r.write_zero:
            from .zero import can_store_zero

            can_store_zero(drivers, [j.name for j in order if j.searched])
        # the one motion guard (motion_guard.py): SIGINT/SIGTERM/SIGHUP/SIGQUIT or a fault → every motor limp
        # (signals held off until it is done), the line says which motors did not answer the torque-off
        with MotionGuard(limp=lambda: limp_all(drivers), what="motor state"):
            autocal = AutoCalRequest(profile.auto, limits, joints=[j.name for j in order], max_lag_rad=max_lag_rad,
                                     gravity=gravity, gravity_model=gravity_model, joint_gravity=joint_gravity)  # fmt: skip
            auto = run_autocal(drivers, autocal, view=view, clock=clock)
    except BaseException:
        limp_all(drivers)
        with contextlib.suppress(Exception):
            close()
        raise
    # the run is over: the joints hold their park angles; nothing is written before this point. Without
    # --write-zero nothing needs them any more: limp now, before the files (a signal during a file's fsync, which no
    # signal interrupts, was handled only once it returned: a held gripper limp 457 ms after SIGHUP, issue 26)
    limped = not r.write_zero
    try:
        if limped:
            limp_all(drivers)
        prior = offsets_by_joint(existing) if existing is not None else {}
        expected: dict[str, tuple[float, float]] = {}
        for j in specs:
            aj = profile.auto.joint(j.name)
            lo, hi = aj.expected_rad(j.lower, j.upper) if aj is not None else (j.lower, j.upper)
            expected[j.name] = (j.lower if lo is None else lo, j.upper if hi is None else hi)
        searched = {o.name for o in auto.joints if o.ok}
        rows = [j for j in specs if j.name in searched]  # the others stay as the existing file has them
        result = auto_sweep_result(
            auto,
            rows,
            prior=prior,
            span_tolerance_rad=math.radians(profile.auto.span_tolerance_deg),
            expected=expected,
            wraps=profile.position_wraps,
            zero_sta=1 if vendor.power_on_half_turn else 0,
        )
        if r.verify:
            if auto.failed:
                raise AutoCalFailedError(
                    f"verification failed for {auto.failure_summary()}; nothing was written", auto
                )
            counts = {n: d.position_count_rad() for n, d in drivers.items()}
            drifts = _drifts(result, rows, prior, expected, r.tolerance_deg, counts)
            code = 1 if any(d.flagged for d in drifts) else 0
            return AutoSweepOutcome(auto, result, None, fmt, None, code, drifts)
        if auto.failed and not partial:
            raise AutoCalFailedError(
                f"auto-calibration failed for {auto.failure_summary()}; nothing was written (pass --partial to "
                "write the joints that passed)",
                auto,
            )
        zeros: dict[str, float] = {}
        # from the first zero stored in flash (irreversible) to the file written, a signal waits (bus_transaction
        # holds it) and comes out after the file: "interrupted after writing ..." (issue 26 item 6, issue 31)
        with contextlib.ExitStack() as held:  # closed on any exception too: nothing stays held
            if r.write_zero and searched:
                held.enter_context(MotionGuard(limp=lambda: limp_all(drivers), what="motor state"))
                zeros = store_zeros(
                    drivers, {o.name: o.stops.offset_rad for o in auto.joints if o.ok}, profile.auto,
                    max_lag_rad=max_lag_rad,
                    before_store=lambda: held.enter_context(transaction()),
                )  # fmt: skip
                result = rezeroed_result(
                    result, zeros, wraps=profile.position_wraps, zero_sta=1 if vendor.power_on_half_turn else 0
                )
            with _all_or_nothing([p for p in (report_path, out_path if rows else None) if p is not None]):
                if report_path is not None:
                    doc = result.to_report()
                    doc["auto"] = auto.to_report()
                    if zeros:
                        doc["zero_stored_at_deg"] = {n: round(math.degrees(q), 4) for n, q in zeros.items()}
                    atomic_write_text(report_path, json.dumps(doc, indent=2) + "\n")
                if rows:
                    write_sweep_files(result, urdf, rows, out_path, fmt, None, existing, profile)
            if zeros:
                zeros_written(drivers, list(zeros))  # the state folder's record of them goes
    finally:
        if not limped:
            limp_all(drivers)
        with contextlib.suppress(Exception):
            close()
    code = 0 if result.ok and not auto.failed else 1
    return AutoSweepOutcome(auto, result, out_path if rows else None, fmt, report_path, code)


def _drifts(
    result: SweepResult,
    rows: Sequence[Any],
    prior: Mapping[str, float],
    expected: Mapping[str, tuple[float, float]],
    tolerance_deg: float,
    count_rad: Mapping[str, float],
) -> tuple[JointDrift, ...]:
    """Per searched joint with a stored offset: the offset its stops give now against the stored one.

    ± one count of its motor's reading, ``count_rad`` (the vendor's: Robstride 8π/65535, Damiao 2·PMAX/65535).
    """
    out = []
    for j in rows:
        if j.name not in prior:
            continue
        js = result[j.name]
        lo, hi = expected[j.name]
        span_error = js.sweep - (hi - lo) if js.method == "two-sided" else 0.0
        out.append(
            offset_drift(
                j.name,
                j.direction,
                js.homing_offset,
                prior[j.name],
                span_error if math.isfinite(span_error) else 0.0,
                count_rad[j.name],
                tolerance_deg,
            )
        )
    return tuple(out)


__all__ += ["AutoCalAbortedError"]
