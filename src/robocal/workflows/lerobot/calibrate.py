"""LeRobot calibration: the current two-step procedure and the legacy (2024) poses, with robocal's fixes.

The calibration follows LeRobot's procedure (torque off → Operating_Mode → mid pose → half-turn homing in
EEPROM → range-of-motion sweep → limits in EEPROM → JSON file), with robocal's fixes:

* the sweep is recorded wrap-aware; a travel that crosses the 0/4095 seam is re-homed so the seam lies outside
  it, instead of being clipped to (≈0, ≈4095) (huggingface/lerobot#3586);
* ``home_after_sweep``: sweep first, then centre the homing on the travel (#3587);
* a Feetech pose at 4095 no longer overflows the sign-magnitude Homing_Offset;
* any exception or Ctrl-C restores every register the procedure changed (Homing_Offset, limits, Drive_Mode,
  Operating_Mode, Phase, Lock) and reads it back, and the file is not written; a finished run puts ``Lock`` back
  as it was (the new calibration, Operating_Mode and Phase are what LeRobot's procedure means to leave);
* full-turn joints (SO ``wrist_roll``, Koch ``shoulder_pan``/``wrist_roll``) may be swept (#4583);
* restoring a file on Dynamixel also writes Drive_Mode.
"""

from __future__ import annotations

import os
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Protocol

from ...backends.servo_bus import ServoBus
from ...core.lerobot import (
    LegacyCalibration,
    MotorCalibration,
    RobotSpec,
    centre_homing,
    half_turn_homing_offset,
    legacy_calibration_from_poses,
    offset_in_register,
)
from ...core.wrap_range import RangeTracker
from ...errors import CalibError, InvalidCalibrationError, UsageError
from ...formats.lerobot import write_current, write_legacy
from .configure import clear_phase_bit4
from .eeprom import _disable_torque, _restore_plan, _write_plan, read_eeprom
from .files import check_calibration_writable
from .guard import arm_guard

__all__ = [
    "CalibrateRequest",
    "CalibrationNotSavedError",
    "CalibrationResult",
    "Operator",
    "RangeView",
    "calibrate",
    "calibrate_legacy",
    "hand_snapshot",
    "save_calibration",
]


class Operator(Protocol):
    """The human (or a simulated one) who moves the arm."""

    def prompt(self, stage: str, message: str) -> None:
        """Show ``message`` and wait for ENTER; ``stage`` is ``"middle"`` or ``"sweep"``."""
        ...

    def sweep_step(self) -> bool:
        """Called once per range-recording loop; return True when the operator has finished the sweep."""
        ...

@dataclass(frozen=True)
class RangeView:
    """What the live range table shows after each reading (per swept motor, ticks)."""

    names: tuple[str, ...]
    present: tuple[int, ...]
    minimum: tuple[int, ...]
    maximum: tuple[int, ...]
    step: int

@dataclass(frozen=True)
class CalibrationResult:
    """Result of :func:`calibrate`.

    Attributes:
        calibration: Motor name → calibration, in bus order.
        path: The JSON file written (None if not written).
        notes: What robocal did differently from LeRobot (seam re-homing, 4095 clamp), one line each.
        naive_ranges: LeRobot's wrap-blind (min, max) per swept motor, for comparison.
    """

    calibration: dict[str, MotorCalibration]
    path: Path | None
    notes: tuple[str, ...] = ()
    naive_ranges: dict[str, tuple[int, int]] = field(default_factory=dict)

class CalibrationNotSavedError(UsageError):
    """The calibration was computed but its file could not be written (full disk, read-only folder, ...).

    The motors' previous EEPROM was written back. ``calibration`` holds the result so the caller can show it
    (``robocal lerobot calibrate`` prints it as LeRobot JSON) and nothing the user did is lost.
    """

    def __init__(self, message: str, calibration: Mapping[str, MotorCalibration]) -> None:
        super().__init__(message)
        self.calibration = dict(calibration)


def save_calibration(
    path: str | os.PathLike[str] | None, calibration: Mapping[str, MotorCalibration]
) -> Path | None:
    """Write ``calibration`` as LeRobot's JSON at ``path`` (atomically); None when there is no path.

    Raises:
        CalibrationNotSavedError: The write failed; the calibration is attached to the error.
    """
    if path is None:
        return None
    try:
        return write_current(path, calibration)
    except CalibError as exc:
        raise CalibrationNotSavedError(str(exc), calibration) from None

@dataclass(frozen=True)
class CalibrateRequest:
    """One run of LeRobot's current calibration (``lerobot calibrate``): which arm, what to write, how to sweep.

    The CLI builds it from its options; Python callers build it directly.

    Attributes:
        spec: The arm.
        path: Where to write the LeRobot JSON (None: do not write).
        home_after_sweep: Sweep first, then choose the homing so the travel is centred on the half turn.
        sweep_full_turn: Also sweep the joints LeRobot forces to 0..4095 (#4583).
        max_steps: Stop the sweep after this many readings (None: until the operator finishes).
        snapshot_port: Keep the EEPROM snapshot in robocal's state folder under this port's name until the run
            ends (:class:`~robocal.workflows.motion.guard.MotionGuard`); None: not kept (a simulated arm).
    """

    spec: RobotSpec
    path: str | os.PathLike[str] | None = None
    home_after_sweep: bool = False
    sweep_full_turn: bool = False
    max_steps: int | None = None
    snapshot_port: str | None = None


def hand_snapshot(bus: ServoBus, spec: RobotSpec) -> dict[str, dict[str, int]]:
    """Every register the hand procedure changes, per motor, as it is now (restored on a fault; ``Lock`` last).

    The calibration EEPROM (:func:`read_eeprom`), ``Operating_Mode``, ``Phase`` where the procedure clears its
    multi-turn bit (Feetech STS) and the EEPROM ``Lock``. ``Torque_Enable`` is not kept: a restore leaves every
    motor limp.
    """
    vs = spec.vendor_spec
    extra = ["Operating_Mode"]
    if vs.multi_turn_phase_bit:
        extra.append("Phase")
    if vs.lock_register is not None:
        extra.append(vs.lock_register)
    before = read_eeprom(bus, spec)
    for m in spec.motors:
        for reg in extra:
            if bus.has_register(m.motor_id, reg):
                before[m.name][reg] = bus.read(reg, m.motor_id)
    return before


def calibrate(
    bus: ServoBus,
    request: CalibrateRequest,
    operator: Operator,
    *,
    on_sweep: Callable[[RangeView], None] | None = None,
    on_status: Callable[[str], None] | None = None,
) -> CalibrationResult:
    """Run LeRobot's current calibration with robocal's fixes and write the JSON file.

    Args:
        bus: The arm's bus.
        request: The arm, the file and the sweep settings (:class:`CalibrateRequest`).
        operator: Moves the arm and confirms steps.
        on_sweep: Called after each reading of the sweep (live table).
        on_status: Called with a one-line status while the previous EEPROM is being restored (and for each
            Ctrl-C deferred meanwhile).

    Returns:
        The calibration, the file written and notes.

    Raises:
        UsageError: The file cannot be written there (checked before any motor is touched).
        CalibrationNotSavedError: The file write failed at the end; EEPROM restored, the result attached.
        DeviceError: Bus failure (EEPROM restored as far as the bus allows).
        KeyboardInterrupt: Re-raised after the EEPROM was restored (Ctrl-C is deferred while restoring); no
            file written. Its argument names the motors and registers that could not be restored.
    """
    req = request
    spec, path, home_after_sweep, sweep_full_turn = req.spec, req.path, req.home_after_sweep, req.sweep_full_turn
    max_steps, snapshot_port = req.max_steps, req.snapshot_port
    if path is not None:
        # refuse an impossible output (read-only folder, full disk, ...) before any EEPROM write or sweep
        check_calibration_writable(path)
    ids = [m.motor_id for m in spec.motors]
    names = [m.name for m in spec.motors]
    res = {m.name: bus.resolution(m.motor_id) for m in spec.motors}
    vs = spec.vendor_spec
    before = hand_snapshot(bus, spec)
    notes: list[str] = []
    rule = spec.homing
    guard = arm_guard(bus, spec, command="lerobot calibrate", on_status=on_status, snapshot_port=snapshot_port)
    with guard:  # any signal or fault from here on: limp, the snapshot written back (motion_guard.py)
        guard.snapshot(before, robot=spec.name)
        _disable_torque(bus, spec)
        if vs.multi_turn_phase_bit:
            clear_phase_bit4(bus, spec)  # multi-turn feedback would break the half-turn homing (#1296)
        for m in spec.motors:
            bus.write("Operating_Mode", m.motor_id, spec.operating_mode)
            if vs.drive_mode_in_hardware:
                bus.write("Drive_Mode", m.motor_id, 1 if m.name in spec.inverted else 0)
        operator.prompt("middle", "Move the arm to the middle of its range of motion and press ENTER")
        # reset_calibration: offsets 0 and full limits, so Present = Actual
        for m in spec.motors:
            bus.write("Homing_Offset", m.motor_id, 0)
            bus.write("Min_Position_Limit", m.motor_id, 0)
            bus.write("Max_Position_Limit", m.motor_id, res[m.name] - 1)
        mid = bus.sync_read("Present_Position", ids)
        offsets: dict[str, int] = {}
        for m in spec.motors:
            offsets[m.name] = half_turn_homing_offset(
                mid[m.motor_id], vendor=spec.vendor, resolution=res[m.name]
            )
            if rule.wraps_per_turn and mid[m.motor_id] % res[m.name] == res[m.name] - 1:
                notes.append(
                    f"{m.name}: mid pose at {res[m.name] - 1}; Homing_Offset clamped to 2047 (no overflow)"
                )
        if not home_after_sweep:
            for m in spec.motors:
                bus.write("Homing_Offset", m.motor_id, offsets[m.name])

        swept = [m for m in spec.motors if sweep_full_turn or m.name not in spec.full_turn]
        swept_ids = [m.motor_id for m in swept]
        if not swept:
            raise UsageError(f"{spec.name}: no motor to sweep")
        operator.prompt("sweep", "Move every joint through its whole range of motion, then press ENTER")
        first = bus.sync_read("Present_Position", swept_ids)
        tracker = RangeTracker(len(swept), period=res[swept[0].name], units="ticks")
        tracker.update([first[i] for i in swept_ids])
        step = 0
        while True:
            done = operator.sweep_step()
            now = bus.sync_read("Present_Position", swept_ids)
            tracker.update([now[i] for i in swept_ids])
            step += 1
            if on_sweep is not None:
                on_sweep(
                    RangeView(
                        tuple(m.name for m in swept),
                        tuple(now[i] for i in swept_ids),
                        tuple(int(v) for v in tracker.minimum),
                        tuple(int(v) for v in tracker.maximum),
                        step,
                    )
                )
            if done or (max_steps is not None and step >= max_steps):
                break

        cals: dict[str, MotorCalibration] = {}
        naive: dict[str, tuple[int, int]] = {}
        for k, m in enumerate(swept):
            r = res[m.name]
            lo, hi = int(tracker.minimum[k]), int(tracker.maximum[k])
            naive[m.name] = (int(tracker.raw_minimum[k]), int(tracker.raw_maximum[k]))
            base = 0 if home_after_sweep else offsets[m.name]
            if lo == hi:
                raise InvalidCalibrationError(
                    f"motor {m.name!r} (id {m.motor_id}) did not move during the sweep"
                )
            if hi - lo >= r - 1:  # the travel covers a whole turn or more
                notes.append(f"{m.name}: swept a full turn; range set to 0..{r - 1}")
                offset, rmin, rmax = offsets[m.name], 0, r - 1
            elif home_after_sweep or lo < 0 or hi > r - 1:  # the travel went through the 0/r-1 seam
                if not home_after_sweep:
                    notes.append(
                        f"{m.name}: the sweep crossed the 0/{r - 1} seam (LeRobot would record "
                        f"{naive[m.name][0]}..{naive[m.name][1]}); re-homed so the seam is outside the travel"
                    )
                shift, rmin, rmax = centre_homing(lo, hi, resolution=r)
                offset = rule.offset_for_shift(base, shift)
            else:
                offset, rmin, rmax = base, lo, hi
            offset, rmin, rmax = offset_in_register(rule, offset, rmin, rmax, r)
            dm = 1 if (vs.drive_mode_in_hardware and m.name in spec.inverted) else 0
            cals[m.name] = MotorCalibration(m.motor_id, dm, offset, rmin, rmax)
        for m in spec.motors:
            if m.name not in cals:  # full-turn joint not swept: LeRobot forces 0..res-1
                dm = 1 if (vs.drive_mode_in_hardware and m.name in spec.inverted) else 0
                cals[m.name] = MotorCalibration(m.motor_id, dm, offsets[m.name], 0, res[m.name] - 1)
        ordered = {n: cals[n] for n in names}
        _write_plan(bus, spec, _restore_plan(bus, spec, ordered))
        if vs.lock_register is not None:  # _disable_torque unlocked every EEPROM: locked again as it was
            for m in spec.motors:
                if vs.lock_register in before[m.name]:
                    bus.write(vs.lock_register, m.motor_id, before[m.name][vs.lock_register])
        written = guard.finish_with(lambda: save_calibration(path, ordered))  # signals held: file = motors
    return CalibrationResult(ordered, written, tuple(notes), naive)

def calibrate_legacy(
    bus: ServoBus,
    spec: RobotSpec,
    operator: Operator,
    *,
    path: str | os.PathLike[str] | None = None,
    aloha_gripper_linear: bool = False,
) -> LegacyCalibration:
    """LeRobot's legacy (2024) zero + rotated pose calibration; nothing is written to the motors.

    Reads Present_Position at the zero pose ("straight horizontal, gripper upwards and closed") and at the
    rotated pose (every joint +90°); ``drive_mode = rotated < zero``; Dynamixel rounds the drive-mode-applied
    rotated pose to a quarter turn, Feetech uses it exactly; ``homing_offset = 1024 − value``. The Feetech
    ``gripper`` is LINEAR (Dynamixel only with ``aloha_gripper_linear``). Writes the legacy JSON when ``path``
    is given.

    Raises:
        UsageError: A Dynamixel motor has torque enabled (LeRobot's precondition).
    """
    ids = [m.motor_id for m in spec.motors]
    if spec.vendor_spec.torque_off_to_calibrate:
        on = [m.name for m in spec.motors if bus.read("Torque_Enable", m.motor_id) != 0]
        if on:
            raise UsageError(
                f"To run calibration, the torque must be disabled on all motors (enabled on {', '.join(on)})."
            )
    if path is not None:
        check_calibration_writable(path)
    operator.prompt("zero", "Move the arm to the zero position and press ENTER")
    zero = bus.sync_read("Present_Position", ids)
    operator.prompt("rotated", "Move the arm to the rotated position (every joint +90°) and press ENTER")
    rotated = bus.sync_read("Present_Position", ids)
    operator.prompt("rest", "Move the arm to the rest position and press ENTER")
    modes = [  # the profile's legacy modes (Feetech gripper LINEAR); Aloha's Dynamixel gripper on request
        "LINEAR" if (aloha_gripper_linear and m.name == "gripper") else m.legacy_mode for m in spec.motors
    ]
    cal = legacy_calibration_from_poses(
        spec.motor_names,
        [zero[i] for i in ids],
        [rotated[i] for i in ids],
        vendor=spec.vendor,
        calib_mode=modes,
    )
    if path is not None:
        write_legacy(path, cal)
    return cal
