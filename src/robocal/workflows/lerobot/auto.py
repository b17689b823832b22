"""``robocal lerobot calibrate --auto``: a LeRobot arm finds its own hard stops and writes LeRobot's calibration.

The joints of the profile's ``auto_calibration`` section are driven into their stops one after the other by
:func:`robocal.workflows.autocal.job.run_autocal` through the servo drivers of :mod:`robocal.backends.servo_joint_driver`
(real registers through the vendor SDK). The result has the manual procedure's conventions
(:func:`robocal.workflows.lerobot.calibrate` with ``home_after_sweep``): per searched joint the range is the two
contact surfaces found, ``range_min``/``range_max`` in Present ticks, and the homing offset puts the middle of
that range at half a turn (Present 2047); the Dynamixel ``drive_mode`` is the profile's. Motors that are not
searched (LeRobot's full-turn joints, ``joints`` left out, failed joints with ``partial``) keep the calibration
their EEPROM holds now.

Safety and all-or-nothing (docs/auto_calibration.md): before anything moves every register the search changes is
read (the snapshot); on Ctrl-C or a fault every motor gets ``Torque_Enable`` 0 in one SYNC_WRITE, latched
Dynamixels are rebooted, and the snapshot is written back (EEPROM and RAM) — the file is not written. A joint
that fails (missing stop, snag, span mismatch) fails the run with its code and reason, EEPROM restored, nothing
written, unless ``partial``.
"""

from __future__ import annotations

import math
import os
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path

from ...backends.servo_bus import ServoBus
from ...core.gravity import GravityModel
from ...core.lerobot import MotorCalibration, RobotSpec, centre_homing, offset_in_register
from ...core.profile_auto import AutoSection
from ...core.stop_search import JointStops
from ...core.vendors import VENDORS
from ...errors import DeviceError, DeviceGoneError, UsageError
from ..autocal.job import AutoCalRequest, run_autocal, select_joints
from ..autocal.model import (
    AutoCalFailedError,
    AutoCalResult,
    AutoView,
    Clock,
    ConfirmStart,
    JointCaps,
    JointDriver,
    joint_driver_class,
)
from ..motion.guard import RestoreReport
from .calibrate import save_calibration
from .eeprom import EEPROM_FIELDS, _restore_plan, _write_plan
from .files import check_calibration_writable
from .guard import LOST_TEXT, arm_guard, limp_arm, restore_registers, silent_round

__all__ = [
    "HOLD_GAINS",
    "HOST_LOSS",
    "MAX_LAG_DEG",
    "WATCHDOG_S",
    "AutoCalibrationRequest",
    "AutoCalibrationResult",
    "auto_calibrate",
    "auto_section",
    "calibration_from_stops",
    "prepare_search",
    "restore_registers",
    "search_registers",
    "snapshot_registers",
]

MAX_LAG_DEG = {n: v.max_lag_deg for n, v in VENDORS.items() if v.max_lag_deg is not None}
"""How far the position goal may lead the joint, per vendor: above the firmware's lag at the torque cap (the
Feetech P gain reaches the cap within ~1–2°, the Dynamixel current-based position gain within ~2–6°). Read
from each vendor's declaration (:attr:`~robocal.core.vendors.VendorSpec.max_lag_deg`)."""

WATCHDOG_S = 0.5
"""The Dynamixel ``Bus_Watchdog`` armed on the searched motors before the first motion (25 × 20 ms)."""
HOST_LOSS = {
    "dynamixel": f"If robocal is killed or the cable is pulled, each moving servo's Bus Watchdog stops it within "
    f"{WATCHDOG_S:g} s.",
    "feetech": "Feetech STS servos have no host-loss watchdog: if robocal is killed or the cable is pulled, a servo "
    "keeps its last goal and pushes with at most its cap until the power is cut (the caps and speeds are kept "
    "low for that reason).",
}
"""What stops the motors when the host is lost, per vendor (said in the clear-workspace prompt)."""

HOLD_GAINS: dict[str, dict[str, dict[str, int]]] = {
    "koch_follower": {"elbow_flex": {"Position_P_Gain": 1500, "Position_I_Gain": 0, "Position_D_Gain": 600}},
}
"""Per arm and motor, the position gains LeRobot's follower writes on every connect (``KochFollower.configure``:
"better PID values to close the gap between recorded states and actions"). The search sets them too: with the
XL330's default gain the elbow, capped at 25 % of its 0.52 N·m, stops short of a pose angle it must hold
against its friction. Snapshotted and written back like every register the search changes."""



@dataclass(frozen=True)
class AutoCalibrationResult:
    """The outcome of :func:`auto_calibrate`.

    Attributes:
        calibration: Motor → calibration, bus order (every motor of the arm).
        auto: The per-joint stop searches (stops, spans, stiffness, tests, times).
        path: The JSON written, or None.
        kept: Motors whose calibration is the one their EEPROM held (not searched or failed with ``partial``).
    """

    calibration: dict[str, MotorCalibration]
    auto: AutoCalResult
    path: Path | None
    kept: tuple[str, ...]

    @property
    def exit_code(self) -> int:
        """0 when every searched joint passed, 1 when written with ``partial`` although one failed."""
        return 1 if self.auto.failed else 0


def auto_section(robot: str | os.PathLike[str]) -> AutoSection:
    """The ``auto_calibration`` section of a LeRobot arm's profile.

    Raises:
        UsageError: The profile has no such section (leader arms cannot drive themselves).
    """
    from ...formats.profiles import builtin_lerobot_profiles, load_profile

    profile = load_profile(robot)
    if profile.auto is None:
        having = sorted(p.name for p in builtin_lerobot_profiles() if p.auto is not None)
        raise UsageError(
            f"robot profile {profile.name} has no auto_calibration section: --auto needs one, with each joint's "
            f"stop angles and search torque (built-in arms that have it: {', '.join(having)}; a leader arm, whose "
            "gears are removed, cannot drive itself; for another follower, write the section into a profile file "
            "of your own, see docs/auto_calibration.md)"
        )
    return profile.auto


def search_registers(bus: ServoBus, spec: RobotSpec, motor_id: int) -> tuple[str, ...]:
    """The registers the search changes on a motor, in the order a restore writes them (EEPROM, RAM, Lock)."""
    vs = spec.vendor_spec
    names = ["Operating_Mode", *EEPROM_FIELDS, *vs.torque_cap_registers]
    motor = next((m.name for m in spec.motors if m.motor_id == motor_id), None)
    names += list(HOLD_GAINS.get(spec.name, {}).get(motor or "", {}))
    if vs.lock_register is not None:
        names.append(vs.lock_register)
    return tuple(n for n in names if bus.has_register(motor_id, n))


def snapshot_registers(bus: ServoBus, spec: RobotSpec, searched: Sequence[str]) -> dict[str, dict[str, int]]:
    """Per motor the registers the search changes (searched motors) or the calibration ones (the others).

    Raises:
        DeviceGoneError: A read failed and no motor answered (that one's retries, then one round, one try each):
            the device is lost; nothing was moved or written.
        DeviceError: A read failed while other motors answer.
    """
    out: dict[str, dict[str, int]] = {}
    answered = False
    for k, m in enumerate(spec.motors):
        names = search_registers(bus, spec, m.motor_id) if m.name in searched else (*EEPROM_FIELDS, "Lock")
        try:
            out[m.name] = {f: bus.read(f, m.motor_id) for f in names if bus.has_register(m.motor_id, f)}
        except DeviceError as exc:
            rest = [o.motor_id for o in spec.motors[k + 1 :]]
            if isinstance(exc, DeviceGoneError) or (not answered and (not rest or silent_round(bus, rest))):
                raise DeviceGoneError(f"{exc}; {LOST_TEXT} before anything was moved or written") from exc
            raise
        answered = True
    return out


def prepare_search(
    bus: ServoBus,
    spec: RobotSpec,
    section: AutoSection,
    searched: Sequence[str],
    clock: Clock,
    period_s: float,
) -> dict[str, JointDriver]:
    """Torque off; per searched motor the search's mode, full-turn limits, homing and RAM limits; the drivers.

    The caller snapshots the registers first (:func:`snapshot_registers`) and writes them back
    (:func:`restore_registers`) when the run ends without a calibration to write.
    """
    drivers: dict[str, JointDriver] = {}
    ids = {m.name: m.motor_id for m in spec.motors}
    lock = spec.vendor_spec.lock_register
    for m in spec.motors:
        bus.write("Torque_Enable", m.motor_id, 0)
        if lock is not None and bus.has_register(m.motor_id, lock):
            bus.write(lock, m.motor_id, 0)
    for name in searched:
        i = ids[name]
        joint = section.joint(name)
        assert joint is not None
        driver = joint_driver_class(spec.vendor)
        offset = driver.prepare_registers(bus, i)
        drv = driver(
            bus,
            name,
            i,
            rated_nm=joint.rated_nm,
            cap_nm=joint.torque_cap_nm,
            clock=clock,
            period_s=period_s,
            homing_offset=offset,
            motor=joint.motor,
        )
        drv.configure(HOLD_GAINS.get(spec.name, {}).get(name, {}), inverted=name in spec.inverted)
        drivers[name] = drv
    return drivers


def calibration_from_stops(
    spec: RobotSpec,
    motor: str,
    resolution: int,
    lower_rad: float,
    upper_rad: float,
    *,
    full_range: bool = False,
) -> MotorCalibration:
    """LeRobot's calibration of one motor from its two contact surfaces (driver frame: unwrapped ticks·2π/res).

    The same rule as the manual procedure's ``home_after_sweep``: the homing centres the travel on half a turn
    (:func:`~robocal.core.lerobot.centre_homing`), the range is the travel in Present ticks; Feetech offsets
    are brought into the sign-magnitude register's reach. The driver frame is Present at ``Homing_Offset`` 0
    (Feetech: modulo a turn; Dynamixel: ``Drive_Mode`` applied). ``full_range``: LeRobot's convention for its
    full-turn joints (SO ``wrist_roll``): the homing as above, the range ``0..resolution − 1``.
    """
    m = spec.motors[spec.motor_names.index(motor)]
    lo = math.ceil(lower_rad * resolution / (2 * math.pi) - 1e-9)
    hi = math.floor(upper_rad * resolution / (2 * math.pi) + 1e-9)
    shift, rmin, rmax = centre_homing(lo, hi, resolution=resolution)
    dm = 1 if (spec.vendor_spec.drive_mode_in_hardware and motor in spec.inverted) else 0
    rule = spec.homing
    offset, rmin, rmax = offset_in_register(rule, rule.offset_for_shift(0, shift), rmin, rmax, resolution)
    if full_range:
        rmin, rmax = 0, resolution - 1
    return MotorCalibration(m.motor_id, dm, offset, rmin, rmax)


def _stop_pair(section: AutoSection, stops: JointStops) -> tuple[float, float]:
    """The two stop surfaces of a passed joint (driver frame); a one-sided joint's other end from the profile."""
    joint = section.joint(stops.name)
    assert joint is not None
    exp_lo, exp_hi = joint.expected_rad(None, None)
    lo = stops.lower.q_stop_rad if stops.lower is not None else None
    hi = stops.upper.q_stop_rad if stops.upper is not None else None
    if lo is None:
        if exp_lo is None:
            raise UsageError(f"joint {stops.name}: a one-sided joint needs lower_deg in the profile")
        lo = exp_lo + stops.offset_rad
    if hi is None:
        if exp_hi is None:
            raise UsageError(f"joint {stops.name}: a one-sided joint needs upper_deg in the profile")
        hi = exp_hi + stops.offset_rad
    return lo, hi


def _eeprom_calibration(spec: RobotSpec, motor: str, regs: Mapping[str, int]) -> MotorCalibration:
    m = spec.motors[spec.motor_names.index(motor)]
    dm = regs.get("Drive_Mode", 0) & 1 if spec.vendor_spec.drive_mode_in_hardware else 0
    return MotorCalibration(
        m.motor_id,
        dm,
        regs.get("Homing_Offset", 0),
        regs.get("Min_Position_Limit", 0),
        regs.get("Max_Position_Limit", 4095),
    )


@dataclass(frozen=True)
class AutoCalibrationRequest:
    """One ``lerobot calibrate --auto`` run: which arm and joints, what to write and how to search.

    The CLI builds it from its options; Python callers build it directly. The joints, motors and file are
    checked by :func:`auto_calibrate` before anything moves.

    Attributes:
        spec: The arm.
        section: Its profile's ``auto_calibration`` section (:func:`auto_section`).
        path: LeRobot JSON to write (None: EEPROM only).
        joints: Subset to search (``--joints``), run in the profile's order.
        partial: Write the joints that passed although others failed (those keep their EEPROM values).
        sweep_full_turn: LeRobot's full-turn joints that were searched get the found range (as the manual
            ``--sweep-full-turn``) instead of ``0..resolution − 1``.
        period_s: Control period.
        max_lag_deg: The most the goal leads the joint (default :data:`MAX_LAG_DEG` of the vendor).
        gravity_model: The arm's gravity model (its URDF's masses,
            :func:`robocal.workflows.lerobot.auto_sim.auto_gravity_model`): each joint's stops are corrected
            for the gravity torque in its profile search pose before the midpoint (docs/auto_calibration.md).
            The URDF joint must turn the way Present_Position grows (LeRobot's ``so101_new_calib`` does).
        snapshot_port: Keep the register snapshot in robocal's state folder under this port's name until the
            run ends cleanly (:mod:`robocal.workflows.motion.snapshot`); None: not kept (a simulated arm).
    """

    spec: RobotSpec
    section: AutoSection
    path: str | os.PathLike[str] | None = None
    joints: Sequence[str] | None = None
    partial: bool = False
    sweep_full_turn: bool = False
    period_s: float = 0.01
    max_lag_deg: float | None = None
    gravity_model: GravityModel | None = None
    snapshot_port: str | None = None


def auto_calibrate(
    bus: ServoBus,
    request: AutoCalibrationRequest,
    *,
    clock: Clock,
    confirm_start: ConfirmStart | None = None,
    view: AutoView | None = None,
    on_status: Callable[[str], None] | None = None,
) -> AutoCalibrationResult:
    """Find every selected joint's stops, then write LeRobot's calibration to the EEPROM and the JSON file.

    Args:
        bus: The arm's bus (real port or a simulator's pseudo-terminal).
        request: The arm, joints, file and search settings (:class:`AutoCalibrationRequest`).
        clock: Time of the control loop (:class:`~robocal.workflows.autocal.job.MonotonicClock` on hardware, the
            simulator's clock in a simulation).
        confirm_start: Asked before anything moves (the clear-workspace prompt); False ends with nothing moved.
        view: Live view (the observer the Robstride auto sweep uses).
        on_status: One-line status while the snapshot is written back.

    Returns:
        The calibration of every motor, the searches, the file written.

    Raises:
        UsageError: An unknown joint, a joint the arm lacks, an unwritable file, or not confirmed (nothing
            moved, nothing written).
        AutoCalFailedError: A joint failed and ``partial`` is not given (EEPROM restored, nothing written;
            exit 3).
        AutoCalAbortedError: A device fault (every motor limp, EEPROM restored; exit 3).
        KeyboardInterrupt: Ctrl-C (:class:`~robocal.errors.SignalInterrupt` for SIGINT, SIGTERM, SIGHUP, SIGQUIT),
            after every motor went limp and the EEPROM was restored.
        CalibrationNotSavedError: The file write failed at the end (EEPROM restored, result attached).
    """
    r = request
    spec, section, path, joints, partial = r.spec, r.section, r.path, r.joints, r.partial
    sweep_full_turn, period_s, max_lag_deg = r.sweep_full_turn, r.period_s, r.max_lag_deg
    gravity_model, snapshot_port = r.gravity_model, r.snapshot_port
    order = select_joints(section, joints, movable_only=True)
    kept_by_profile = [j.name for j in order if not j.searched]  # stops: none (a full-turn joint): never moves
    if len(kept_by_profile) == len(order):
        raise UsageError(f"no joint to search: {', '.join(kept_by_profile)} have no hard stops in the profile")
    missing = [j.name for j in order if j.name not in spec.motor_names]
    if missing:
        raise UsageError(
            f"{spec.name} has no motor(s) {', '.join(missing)} named by its auto_calibration section"
        )
    if path is not None:
        check_calibration_writable(path)
    searched = [j.name for j in order if j.searched]  # stops: none joints never move
    caps = JointCaps(order, HOST_LOSS.get(spec.vendor, ""))
    if confirm_start is not None and not confirm_start(tuple(searched), caps):
        raise UsageError("not confirmed: nothing moved, nothing written")
    lag = math.radians(max_lag_deg if max_lag_deg is not None else MAX_LAG_DEG[spec.vendor])
    ids = {m.name: m.motor_id for m in spec.motors}
    before = snapshot_registers(bus, spec, searched)
    failed: tuple[AutoCalResult, RestoreReport | None] | None = None
    guard = arm_guard(
        bus, spec, command="lerobot calibrate --auto", on_status=on_status, snapshot_port=snapshot_port
    )
    with guard:  # from the first write on: limp + restore on any signal or fault (motion_guard.py)
        guard.snapshot(before, robot=spec.name, ids={m.name: m.motor_id for m in spec.motors})
        drivers = prepare_search(bus, spec, section, searched, clock, period_s)
        arm = getattr(bus, "arm_watchdog", None)  # Dynamixel; Feetech STS has no host-loss watchdog
        if arm is not None:
            arm([ids[n] for n in searched], WATCHDOG_S)
        auto = run_autocal(  # the stops: none joints too: reported not_searched, never driven
            drivers,
            AutoCalRequest(section, joints=[j.name for j in order], max_lag_rad=lag, gravity_model=gravity_model),
            view=view,
            clock=clock,
        )
        limp_arm(bus, spec)
        if auto.failed and not partial:
            failed = (auto, guard.restore_now())
        else:
            cals: dict[str, MotorCalibration] = {}
            kept: list[str] = []
            passed = {o.name: o for o in auto.joints if o.ok}
            for m in spec.motors:
                o = passed.get(m.name)
                if o is None:
                    cals[m.name] = _eeprom_calibration(spec, m.name, before[m.name])
                    kept.append(m.name)
                    continue
                lo, hi = _stop_pair(section, o.stops)
                cals[m.name] = calibration_from_stops(
                    spec,
                    m.name,
                    bus.resolution(m.motor_id),
                    lo,
                    hi,
                    full_range=m.name in spec.full_turn and not sweep_full_turn,
                )
            plan = _restore_plan(bus, spec, cals)
            for name in searched:  # the search's RAM values and modes back as they were; then the calibration
                if name not in passed:
                    continue
                for reg, value in before[name].items():
                    if reg not in EEPROM_FIELDS and reg not in ("Operating_Mode", "Lock"):
                        bus.write(reg, ids[name], value)
            _write_plan(bus, spec, plan)
            for name in searched:
                if name in passed:
                    bus.write("Operating_Mode", ids[name], spec.operating_mode)
                else:  # failed with --partial: everything as it was
                    for reg, value in before[name].items():
                        bus.write(reg, ids[name], value)
            for m in spec.motors:  # _write_plan unlocked every Feetech EEPROM
                if "Lock" in before[m.name]:
                    bus.write("Lock", m.motor_id, before[m.name]["Lock"])
            written = guard.finish_with(lambda: save_calibration(path, cals))  # signals held: file = motors
    if failed is not None:
        auto, report = failed
        if report is not None and getattr(report, "lost", None):  # the cause is the device, not the search
            raise AutoCalFailedError(f"auto-calibration stopped at {auto.failure_summary()}: {report.summary()}", auto)
        done = report.summary() if report is not None else "nothing to restore"
        raise AutoCalFailedError(
            f"auto-calibration failed for {auto.failure_summary()}; nothing was written, {done} "
            "(pass --partial to write the joints that passed)",
            auto,
        )
    return AutoCalibrationResult(cals, auto, written, tuple(kept))
