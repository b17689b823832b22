"""``robocal lerobot calibrate --auto --verify``: touch the stops again and say how far the stored calibration drifted.

The same stop search as ``--auto`` (:func:`robocal.workflows.lerobot.auto.auto_calibrate`: the profile's joints
driven into their stops at its low torque caps, under the motion guard), then every register the search changed
is written back from the snapshot (the EEPROM ends as it began) and no file is written. Per joint, the stops found
are compared with where the stored calibration (LeRobot's JSON) has them: its ``range_min``/``range_max`` at its
``Homing_Offset``, in the motor's actual ticks. The drift is the shift of the middle of the range (LeRobot's
DEGREES zero): ``((found_lo − stored_lo) + (found_hi − stored_hi)) / 2``; its uncertainty combines half the
disagreement of the two ends (a span that changed is not an offset) with one encoder count (a full-turn range,
LeRobot's ``wrist_roll``, is not its stops: only its middle is compared, ± one count). A joint whose ``|drift|``
exceeds the tolerance is flagged.
"""

from __future__ import annotations

import math
import os
import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, replace
from pathlib import Path

from ...backends.servo_bus import ServoBus
from ...core.gravity import GravityModel
from ...core.health.drift import JointDrift, range_drift
from ...core.lerobot import MotorCalibration, RobotSpec
from ...core.profile_auto import AutoJoint, AutoSection
from ...core.wrap_range import RangeTracker
from ...errors import CalibError, UsageError
from ..autocal.job import AutoCalRequest, run_autocal, select_joints
from ..autocal.model import AutoCalFailedError, AutoCalResult, AutoView, Clock, ConfirmStart, JointCaps
from .auto import (
    HOST_LOSS,
    MAX_LAG_DEG,
    WATCHDOG_S,
    _eeprom_calibration,
    _stop_pair,
    prepare_search,
    snapshot_registers,
)
from .calibrate import Operator, RangeView
from .eeprom import calibration_writes
from .files import read_calibration_file
from .guard import arm_guard, limp_arm

__all__ = [
    "DEFAULT_TOLERANCE_DEG",
    "HandVerifyResult",
    "JointDrift",
    "VerifyRequest",
    "VerifyResult",
    "check_hand",
    "check_stored",
    "stored_stops_ticks",
    "verify_by_hand",
    "verify_calibration",
]

DEFAULT_TOLERANCE_DEG = 2.0
"""``--tolerance-deg``: above the stop search's reproducibility (a few counts, 0.1-0.3° on the simulated SO-101)
and a hand calibration's scatter of its range's middle, below where a zero error shows at the gripper (2° on a
shoulder joint of a 30 cm arm moves the gripper ~1 cm)."""


@dataclass(frozen=True)
class VerifyRequest:
    """One ``--auto --verify`` run.

    Attributes:
        spec: The arm.
        section: Its profile's ``auto_calibration`` section.
        path: The stored calibration (LeRobot's JSON) to verify.
        joints: Subset to search (``--joints``).
        tolerance_deg: Drift above which a joint is flagged, degrees.
        period_s: Control period.
        max_lag_deg: The most the goal leads the joint (default: the vendor's).
        gravity_model: The arm's gravity model (as for ``--auto``; the stored stops were corrected with it).
        snapshot_port: Keep the register snapshot under this port's name until the run ends (None: a simulator).
    """

    spec: RobotSpec
    section: AutoSection
    path: str | os.PathLike[str]
    joints: Sequence[str] | None = None
    tolerance_deg: float = DEFAULT_TOLERANCE_DEG
    period_s: float = 0.01
    max_lag_deg: float | None = None
    gravity_model: GravityModel | None = None
    snapshot_port: str | None = None

    def __post_init__(self) -> None:
        if not (math.isfinite(self.tolerance_deg) and self.tolerance_deg > 0):
            raise UsageError(
                f"--tolerance-deg: expected a positive number of degrees, got {self.tolerance_deg!r}"
            )


@dataclass(frozen=True)
class VerifyResult:
    """What ``--verify`` measured.

    Attributes:
        joints: Per searched joint, its drift (in the profile's search order).
        auto: The stop searches.
        tolerance_deg: The tolerance used.
        search_s: Time the searches took on the run's clock, s.
        wall_s: Wall time of the whole run, s.
    """

    joints: tuple[JointDrift, ...]
    auto: AutoCalResult
    tolerance_deg: float
    search_s: float
    wall_s: float

    @property
    def exit_code(self) -> int:
        """0 when every joint is within the tolerance, else 1."""
        return 1 if any(j.flagged for j in self.joints) else 0


def stored_stops_ticks(spec: RobotSpec, cal: MotorCalibration, resolution: int) -> tuple[float, float]:
    """Where a stored calibration has a motor's two range ends, in its actual ticks (modulo a turn)."""
    rule = spec.homing
    sign = -1 if (spec.vendor_spec.drive_mode_in_hardware and cal.drive_mode) else 1
    a = sign * (cal.range_min - rule.offset_sign * cal.homing_offset)
    b = sign * (cal.range_max - rule.offset_sign * cal.homing_offset)
    return float(min(a, b)), float(max(a, b))


def check_stored(request: VerifyRequest) -> tuple[dict[str, MotorCalibration], list[AutoJoint], list[str]]:
    """The stored calibration, the joints in order and the searched ones (checked before anything opens).

    Raises:
        UsageError: No file, a joint it lacks, no joint with stops.
        FileFormatError: A file that is not LeRobot's calibration JSON.
    """
    r = request
    if not os.path.exists(r.path):  # a folder there is the reader's "is a directory" error
        raise UsageError(f"no stored calibration at {os.fspath(r.path)} to verify (calibrate first)")
    stored = read_calibration_file(Path(r.path))
    order = list(select_joints(r.section, r.joints, movable_only=True))
    searched = [j.name for j in order if j.searched]
    if not searched:
        raise UsageError("no joint to verify: the chosen joints have no hard stops in the profile")
    lacking = [n for n in searched if n not in stored]
    if lacking:
        raise UsageError(f"calibration {os.fspath(r.path)} has no entry for motor(s) {', '.join(lacking)}")
    return stored, order, searched


def _check_fits(
    bus: ServoBus,
    spec: RobotSpec,
    stored: Mapping[str, MotorCalibration],
    searched: Sequence[str],
    path: str | os.PathLike[str],
) -> None:
    """Every stored register value of a searched motor fits its register (no bus I/O): else it was never on this arm.

    The drift is taken modulo a turn, so a stored ``homing_offset`` of 2147483647 (4095 modulo 4096) read "ok".

    Raises:
        UsageError: A value no register of the motor can hold (nothing moved).
    """
    for name, register, motor_id, value in calibration_writes(bus, spec, {n: stored[n] for n in searched}):
        try:
            bus.check_write(register, motor_id, value)
        except CalibError as exc:
            raise UsageError(
                f"calibration {os.fspath(path)}: motor {name!r}: {register} {value} cannot be on the motor "
                f"({exc}); nothing moved"
            ) from None


def verify_calibration(
    bus: ServoBus,
    request: VerifyRequest,
    *,
    clock: Clock,
    confirm_start: ConfirmStart | None = None,
    view: AutoView | None = None,
    on_status: Callable[[str], None] | None = None,
) -> VerifyResult:
    """Search the stops again, write every changed register back, and measure each joint's drift.

    Args:
        bus: The arm's bus.
        request: The arm, the stored calibration, the joints and the tolerance.
        clock: The control loop's clock.
        confirm_start: Asked before anything moves.
        view: Live view of the searches.
        on_status: One-line status while the snapshot is written back.

    Returns:
        Per joint the drift and its uncertainty, the searches.

    Raises:
        UsageError: No stored calibration, a joint it lacks, not confirmed (nothing moved).
        AutoCalFailedError: A joint's search failed (registers written back; exit 3).
        AutoCalAbortedError: A device fault (every motor limp, registers written back; exit 3).
        KeyboardInterrupt: Ctrl-C, after every motor went limp and the registers were written back.
    """
    wall0 = time.monotonic()
    r = request
    spec, section = r.spec, r.section
    stored, order, searched = check_stored(r)
    _check_fits(bus, spec, stored, searched, r.path)
    caps = JointCaps(order, HOST_LOSS.get(spec.vendor, ""))
    if confirm_start is not None and not confirm_start(tuple(searched), caps):
        raise UsageError("not confirmed: nothing moved, nothing written")
    lag = math.radians(r.max_lag_deg if r.max_lag_deg is not None else MAX_LAG_DEG[spec.vendor])
    ids = {m.name: m.motor_id for m in spec.motors}
    before = snapshot_registers(bus, spec, searched)
    t0 = clock.now()
    guard = arm_guard(
        bus,
        spec,
        command="lerobot calibrate --auto --verify",
        on_status=on_status,
        snapshot_port=r.snapshot_port,
    )
    with guard:  # limp + restore on any signal or fault; at the end the snapshot is written back in any case
        guard.snapshot(before, robot=spec.name, ids=ids)
        drivers = prepare_search(bus, spec, section, searched, clock, r.period_s)
        arm = getattr(bus, "arm_watchdog", None)
        if arm is not None:
            arm([ids[n] for n in searched], WATCHDOG_S)
        auto = run_autocal(
            drivers,
            AutoCalRequest(section, joints=[j.name for j in order], max_lag_rad=lag, gravity_model=r.gravity_model),
            view=view,
            clock=clock,
        )
        limp_arm(bus, spec)
        report = guard.restore_now()
    search_s = clock.now() - t0
    if auto.failed:
        done = report.summary() if report is not None else "nothing to restore"
        raise AutoCalFailedError(
            f"verification failed for {auto.failure_summary()}; nothing was written, {done}", auto
        )
    drifts = _drifts(bus, spec, section, auto, stored, r.tolerance_deg)
    return VerifyResult(drifts, auto, r.tolerance_deg, search_s, time.monotonic() - wall0)


def _drifts(
    bus: ServoBus,
    spec: RobotSpec,
    section: AutoSection,
    auto: AutoCalResult,
    stored: Mapping[str, MotorCalibration],
    tolerance_deg: float,
) -> tuple[JointDrift, ...]:
    ids = {m.name: m.motor_id for m in spec.motors}
    out = []
    for o in auto.joints:
        if not o.ok or o.name not in stored:
            continue
        res = bus.resolution(ids[o.name])
        found = _stop_pair(section, o.stops)
        out.append(
            range_drift(o.name, found, stored_stops_ticks(spec, stored[o.name], res), res, tolerance_deg)
        )
    return tuple(out)


@dataclass(frozen=True)
class HandVerifyResult:
    """What a by-hand ``--verify`` measured (an arm that cannot drive itself: a leader).

    Attributes:
        joints: Per motor with stops (LeRobot's full-turn motors left out), its drift.
        tolerance_deg: The tolerance used.
        readings: Readings taken while the operator moved the arm.
    """

    joints: tuple[JointDrift, ...]
    tolerance_deg: float
    readings: int

    @property
    def exit_code(self) -> int:
        """0 when every joint is within the tolerance, else 1."""
        return 1 if any(j.flagged for j in self.joints) else 0


def check_hand(
    spec: RobotSpec, path: str | os.PathLike[str], tolerance_deg: float
) -> dict[str, MotorCalibration]:
    """The stored calibration of a by-hand verify, checked (before the port opens).

    Raises:
        UsageError: No file, a motor it lacks, a bad tolerance.
        FileFormatError: A file that is not LeRobot's calibration JSON.
    """
    if not (math.isfinite(tolerance_deg) and tolerance_deg > 0):
        raise UsageError(f"--tolerance-deg: expected a positive number of degrees, got {tolerance_deg!r}")
    if not os.path.exists(path):
        raise UsageError(f"no stored calibration at {os.fspath(path)} to verify (calibrate first)")
    stored = read_calibration_file(Path(path))
    lacking = [n for n in spec.motor_names if n not in stored]
    if lacking:
        raise UsageError(f"calibration {os.fspath(path)} has no entry for motor(s) {', '.join(lacking)}")
    return stored


def verify_by_hand(
    bus: ServoBus,
    spec: RobotSpec,
    path: str | os.PathLike[str],
    operator: Operator,
    *,
    tolerance_deg: float = DEFAULT_TOLERANCE_DEG,
    on_sweep: Callable[[RangeView], None] | None = None,
) -> HandVerifyResult:
    """Read-only: the operator pushes every joint into both its stops; each one's drift from the stored range.

    Only ``Present_Position`` and ``Homing_Offset`` (and ``Drive_Mode``) are read; nothing is written to the arm
    or to a file. The extremes reached (unwrapped across the encoder seam) are taken as the stops: a joint not
    pushed into a stop shows as ends that moved differently, a large uncertainty, not as a drift.

    Raises:
        UsageError: No stored calibration, a motor it lacks, a bad tolerance.
    """
    stored = check_hand(spec, path, tolerance_deg)
    motors = [m for m in spec.motors if m.name not in spec.full_turn]
    ids = [m.motor_id for m in motors]
    res = bus.resolution(ids[0])
    in_eeprom = {
        m.name: _eeprom_calibration(
            spec,
            m.name,
            {
                f: bus.read(f, m.motor_id)
                for f in ("Homing_Offset", "Drive_Mode")
                if bus.has_register(m.motor_id, f)
            },
        )
        for m in motors
    }
    operator.prompt(
        "sweep", "Push every joint into both of its hard stops, then press ENTER (nothing is written)"
    )
    first = bus.sync_read("Present_Position", ids)
    tracker = RangeTracker(len(ids), period=res, units="ticks")
    tracker.update([first[i] for i in ids])
    readings = 1
    done = False
    while not done:
        done = operator.sweep_step()
        now = bus.sync_read("Present_Position", ids)
        tracker.update([now[i] for i in ids])
        readings += 1
        if on_sweep is not None:
            on_sweep(
                RangeView(
                    tuple(m.name for m in motors),
                    tuple(int(now[i]) for i in ids),
                    tuple(int(v) for v in tracker.minimum),
                    tuple(int(v) for v in tracker.maximum),
                    readings,
                )
            )
    out = []
    for k, m in enumerate(motors):
        reached = replace(
            in_eeprom[m.name], range_min=int(tracker.minimum[k]), range_max=int(tracker.maximum[k])
        )
        lo, hi = stored_stops_ticks(spec, reached, res)
        found = (lo * 2 * math.pi / res, hi * 2 * math.pi / res)
        out.append(
            range_drift(m.name, found, stored_stops_ticks(spec, stored[m.name], res), res, tolerance_deg)
        )
    return HandVerifyResult(tuple(out), tolerance_deg, readings)
