"""LeRobot calibration jobs: current two-step calibration, restore, EEPROM check, migration, URDF joint map.

The calibration follows LeRobot's procedure (torque off → Operating_Mode → mid pose → half-turn homing in
EEPROM → range-of-motion sweep → limits in EEPROM → JSON file), with robocal's fixes:

* the sweep is recorded wrap-aware; a travel that crosses the 0/4095 seam is re-homed so the seam lies outside
  it, instead of being clipped to (≈0, ≈4095) (huggingface/lerobot#3586);
* ``home_after_sweep``: sweep first, then centre the homing on the travel (#3587);
* a Feetech pose at 4095 no longer overflows the sign-magnitude Homing_Offset;
* any exception or Ctrl-C restores every motor's previous Homing_Offset, limits and Drive_Mode, and the file
  is not written;
* full-turn joints (SO ``wrist_roll``, Koch ``shoulder_pan``/``wrist_roll``) may be swept (#4583);
* restoring a file on Dynamixel also writes Drive_Mode.
"""

from __future__ import annotations

import contextlib
import math
import os
import signal
import threading
from collections.abc import Callable, Iterator, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Protocol

from ..backends.servo_bus import ServoBus
from ..core.jointmap import RobotCalibration
from ..core.lerobot import (
    LegacyCalibration,
    MotorCalibration,
    RobotSpec,
    centre_homing,
    half_turn_homing_offset,
    legacy_calibration_from_poses,
)
from ..core.wrap_range import RangeTracker
from ..errors import CalibError, InvalidCalibrationError, UsageError
from ..fileio import check_output_path
from ..formats.lerobot import write_current, write_legacy

__all__ = [
    "CalibrationNotSavedError",
    "CalibrationResult",
    "Difference",
    "Operator",
    "RollbackReport",
    "SweepView",
    "calibrate",
    "calibrate_legacy",
    "check",
    "clear_phase_bit4",
    "configure",
    "export_joint_map",
    "legacy_to_current",
    "norm_modes",
    "open_bus",
    "read_eeprom",
    "restore",
    "robot_names",
    "robot_spec",
]

EEPROM_FIELDS = ("Homing_Offset", "Min_Position_Limit", "Max_Position_Limit", "Drive_Mode")


class Operator(Protocol):
    """The human (or a simulated one) who moves the arm."""

    def prompt(self, stage: str, message: str) -> None:
        """Show ``message`` and wait for ENTER; ``stage`` is ``"middle"`` or ``"sweep"``."""
        ...

    def sweep_step(self) -> bool:
        """Called once per range-recording loop; return True when the operator has finished the sweep."""
        ...


@dataclass(frozen=True)
class SweepView:
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


def robot_names() -> tuple[str, ...]:
    """Names of the built-in LeRobot arm profiles (``koch_follower``, ..., ``so101_leader``), sorted."""
    from ..formats.profiles import builtin_lerobot_profiles

    return tuple(p.name for p in builtin_lerobot_profiles())


def robot_spec(robot: str | os.PathLike[str]) -> RobotSpec:
    """The :class:`RobotSpec` of a built-in LeRobot arm (``so101_follower``, ...) or of a profile file.

    Raises:
        UsageError: Neither a built-in LeRobot arm nor a profile file of one.
        FileFormatError: The profile file is malformed.
    """
    from ..formats.profiles import load_profile

    text = os.fspath(robot)
    names = robot_names()
    if text not in names and not (text.endswith((".yaml", ".yml")) and Path(text).is_file()):
        raise UsageError(f"unknown robot {text!r}; valid: {', '.join(names)} (or a robot profile file)")
    return RobotSpec.from_profile(load_profile(text))


def open_bus(spec: RobotSpec, port: str, *, retries: int = 3) -> ServoBus:
    """Open the vendor-SDK bus of an arm on ``port``."""
    motors = {m.motor_id: m.model for m in spec.motors}
    if spec.vendor == "feetech":
        from ..backends.feetech import FeetechBus

        return FeetechBus(port, motors, retries=retries)
    from ..backends.dynamixel import DynamixelBus

    return DynamixelBus(port, motors, retries=retries)


def read_eeprom(bus: ServoBus, spec: RobotSpec) -> dict[str, dict[str, int]]:
    """Calibration EEPROM registers (Homing_Offset, limits, Drive_Mode where present) per motor name."""
    out: dict[str, dict[str, int]] = {}
    for m in spec.motors:
        out[m.name] = {f: bus.read(f, m.motor_id) for f in EEPROM_FIELDS if bus.has_register(m.motor_id, f)}
    return out


@dataclass(frozen=True)
class RollbackReport:
    """What writing a :func:`read_eeprom` snapshot back achieved, per motor and register.

    Attributes:
        restored: Names of the motors whose registers were all written back and read
            back equal (or, where the read-back failed, acknowledged).
        not_restored: ``"motor 'name' (id N)"`` → registers that were not written back (or read back
            different), in write order.
        deferred_interrupts: Ctrl-C presses received (and deferred) while restoring.
    """

    restored: tuple[str, ...]
    not_restored: dict[str, tuple[str, ...]]
    deferred_interrupts: int = 0

    def summary(self) -> str:
        """One clause: everything restored, or exactly which motors and registers were and were not."""
        if not self.not_restored:
            return "previous EEPROM values written back"
        bad = "; ".join(f"{motor}: {', '.join(regs)}" for motor, regs in self.not_restored.items())
        good = ", ".join(self.restored) if self.restored else "no motor"
        return f"could not write the previous EEPROM back to {bad} (restored: {good})"


@contextlib.contextmanager
def _defer_sigint(on_status: Callable[[str], None] | None) -> Iterator[list[int]]:
    """Hold off Ctrl-C (SIGINT) while the block runs; yields a one-element list counting deferred presses.

    Only the main thread can install a handler; elsewhere the block runs unchanged (the rollback then catches a
    KeyboardInterrupt per write and carries on).
    """
    count = [0]
    installed = False
    previous: object = None
    if threading.current_thread() is threading.main_thread():
        previous = signal.getsignal(signal.SIGINT)
        if previous is not None:

            def deferred(signum: int, frame: object) -> None:
                count[0] += 1
                if on_status is not None:
                    # never let the message break the rollback (e.g. a re-entrant write to the same stream)
                    with contextlib.suppress(Exception):
                        on_status("still restoring the previous EEPROM; Ctrl-C is ignored until it is done")

            signal.signal(signal.SIGINT, deferred)
            installed = True
    try:
        yield count
    finally:
        if installed:
            signal.signal(signal.SIGINT, previous)  # type: ignore[arg-type]


def _rollback(
    bus: ServoBus,
    spec: RobotSpec,
    before: Mapping[str, Mapping[str, int]],
    on_status: Callable[[str], None] | None = None,
) -> RollbackReport:
    """Write a :func:`read_eeprom` snapshot back, motor by motor, as far as the bus allows, and check it.

    Ctrl-C is deferred until every motor has been tried (a second Ctrl-C no longer stops the rollback half
    way); a KeyboardInterrupt raised inside a write (outside the main thread) retries that write. A motor that
    fails (silent, error status) is skipped after its first failed write so the others are still restored.
    Every restored motor is then read back and compared with the snapshot.

    Returns:
        Which motors were restored and which registers of which motors were not.
    """
    label = {m.name: f"motor {m.name!r} (id {m.motor_id})" for m in spec.motors}
    restored: list[str] = []
    not_restored: dict[str, tuple[str, ...]] = {}
    with _defer_sigint(
        on_status
    ) as deferred:  # first: a Ctrl-C while the status line is shown is deferred too
        if on_status is not None:
            on_status("restoring the previous EEPROM of every motor…")
        interrupts = 0
        for m in spec.motors:
            regs = [(f, v) for f, v in before.get(m.name, {}).items() if bus.has_register(m.motor_id, f)]
            done: list[str] = []
            try:
                for f, v in regs:
                    for attempt in range(3):
                        try:
                            bus.write(f, m.motor_id, v)
                            break
                        except KeyboardInterrupt:
                            interrupts += 1
                            if attempt == 2:
                                raise CalibError("interrupted three times") from None
                    done.append(f)
                try:
                    now = {f: bus.read(f, m.motor_id) for f, _v in regs}
                except CalibError:
                    now = dict(regs)  # acknowledged writes; the read-back itself failed
                done = [f for f in done if now[f] == dict(regs)[f]]
            except CalibError:
                pass
            missing = tuple(f for f, _v in regs if f not in done)
            if missing:
                not_restored[label[m.name]] = missing
            else:
                restored.append(m.name)
    return RollbackReport(tuple(restored), not_restored, deferred[0] + interrupts)


def _reraise_after_rollback(exc: BaseException, report: RollbackReport) -> None:
    """Re-raise ``exc`` with what the rollback did (one message line); other exceptions pass unchanged.

    A CalibError keeps its type (so its exit code) and gains ``"; previous EEPROM values written back"`` or
    exactly which motors and registers could not be restored; a KeyboardInterrupt gains the latter as its
    argument (no argument: everything was restored).
    """
    note = report.summary()
    if report.not_restored and isinstance(exc, KeyboardInterrupt):
        raise KeyboardInterrupt(note) from None
    if isinstance(exc, CalibrationNotSavedError):
        raise CalibrationNotSavedError(f"{exc}; {note}", exc.calibration) from exc
    if isinstance(exc, CalibError):
        raise type(exc)(f"{exc}; {note}") from exc


def _disable_torque(bus: ServoBus, spec: RobotSpec) -> None:
    for m in spec.motors:
        bus.write("Torque_Enable", m.motor_id, 0)
        if bus.has_register(m.motor_id, "Lock"):
            bus.write("Lock", m.motor_id, 0)


def clear_phase_bit4(bus: ServoBus, spec: RobotSpec) -> list[int]:
    """Clear bit 4 of Phase on sts3215 motors (single-turn angle feedback; huggingface/lerobot#3373).

    Writes only where the bit is set (0b00010000 → 0, 0xFF → 0b11101111, 0 → no write).

    Returns:
        Ids of the motors written.
    """
    written = []
    for m in spec.motors:
        if m.model != "sts3215":
            continue
        phase = bus.read("Phase", m.motor_id)
        if phase & 0x10:
            bus.write("Phase", m.motor_id, phase & ~0x10 & 0xFF)
            written.append(m.motor_id)
    return written


def configure(
    bus: ServoBus,
    spec: RobotSpec,
    *,
    calibration: Mapping[str, MotorCalibration] | None = None,
    gripper_open_pos: float = 50.0,
) -> list[tuple[str, str, int]]:
    """LeRobot's ``configure()`` presets (torque stays off, except the Koch leader's gripper trigger).

    Every arm: torque off (Feetech also Lock 0), Return_Delay_Time 0. Feetech (SO): Maximum_Acceleration and
    Acceleration 254, Phase bit 4 cleared on sts3215, Operating_Mode 0; the follower also P/I/D 16/0/32 and
    gripper Max_Torque_Limit 500, Protection_Current 250, Overload_Torque 25. Dynamixel (Koch): extended position
    (4) except the gripper current-based position (5); the follower's elbow_flex Position P/I/D 1500/0/600.

    Koch leader gripper trigger (LeRobot's order): with ``calibration`` given, the gripper's torque is enabled
    and ``Goal_Position = gripper_open_pos`` written (RANGE_0_100, unnormalised like LeRobot), so the gripper
    springs back open when squeezed. LeRobot also enables the torque without a calibration (holding whatever
    goal the motor has); robocal then skips the trigger. LeRobot's followers re-enable torque afterwards;
    robocal leaves it off.

    Returns:
        ``(motor, register, value)`` for every register written, in order (Phase only where changed).
    """
    written: list[tuple[str, str, int]] = []

    def put(name: str, motor_id: int, register: str, value: int) -> None:
        bus.write(register, motor_id, value)
        written.append((name, register, value))

    for m in spec.motors:  # torque off first (EEPROM writes)
        put(m.name, m.motor_id, "Torque_Enable", 0)
        if bus.has_register(m.motor_id, "Lock"):
            put(m.name, m.motor_id, "Lock", 0)
    for m in spec.motors:
        put(m.name, m.motor_id, "Return_Delay_Time", 0)
    follower = spec.kind == "robots"
    if spec.vendor == "feetech":
        by_id = {m.motor_id: m.name for m in spec.motors}
        for i in clear_phase_bit4(bus, spec):
            written.append((by_id[i], "Phase", bus.read("Phase", i)))
        for m in spec.motors:
            presets = [("Maximum_Acceleration", 254), ("Acceleration", 254), ("Operating_Mode", 0)]
            if follower:
                presets += [("P_Coefficient", 16), ("I_Coefficient", 0), ("D_Coefficient", 32)]
                if m.name == "gripper":
                    presets += [
                        ("Max_Torque_Limit", 500),
                        ("Protection_Current", 250),
                        ("Overload_Torque", 25),
                    ]
            for reg, value in presets:
                put(m.name, m.motor_id, reg, value)
        return written
    for m in spec.motors:
        put(m.name, m.motor_id, "Operating_Mode", 5 if m.name == "gripper" else 4)
    if follower:
        elbow = next(m for m in spec.motors if m.name == "elbow_flex")
        for reg, value in (("Position_P_Gain", 1500), ("Position_I_Gain", 0), ("Position_D_Gain", 600)):
            put(elbow.name, elbow.motor_id, reg, value)
    elif calibration is not None:
        gripper = next(m for m in spec.motors if m.name == "gripper")
        if gripper.name not in calibration:
            raise InvalidCalibrationError("calibration has no entry for motor 'gripper'")
        from ..core.lerobot.normalisation import unnormalize

        goal = int(
            unnormalize(
                float(gripper_open_pos), calibration[gripper.name], "range_0_100", apply_drive_mode=False
            )
        )
        put(gripper.name, gripper.motor_id, "Torque_Enable", 1)
        put(gripper.name, gripper.motor_id, "Goal_Position", goal)
    return written


def norm_modes(
    spec: RobotSpec, *, use_degrees: bool | None = None, overrides: Mapping[str, str] | None = None
) -> tuple[str, ...]:
    """LeRobot's norm mode per motor (bus order) for a ``use_degrees`` setting, with per-joint overrides.

    ``use_degrees=None`` keeps LeRobot's default for the robot (SO arms DEGREES since v0.4.4, Koch
    RANGE_M100_100). True: every motor but the gripper in DEGREES; False: RANGE_M100_100. The gripper stays
    RANGE_0_100 (LeRobot refuses DEGREES there). ``overrides`` (motor → mode) win over all of that.

    Raises:
        UsageError: An override names an unknown motor or mode.
    """
    from ..core.lerobot.normalisation import NormMode

    valid = {v.value for v in NormMode}
    over = dict(overrides or {})
    unknown = sorted(set(over) - set(spec.motor_names))
    if unknown:
        raise UsageError(
            f"--modes: unknown motor(s) {', '.join(unknown)} on a {spec.name}; valid: {', '.join(spec.motor_names)}"
        )
    out = []
    for m in spec.motors:
        if m.name in over:
            mode = over[m.name].strip().lower()
            if mode not in valid:
                raise UsageError(
                    f"--modes {m.name}={over[m.name]}: expected one of {', '.join(sorted(valid))}"
                )
        elif use_degrees is None or m.name == "gripper":
            mode = m.norm_mode
        else:
            mode = "degrees" if use_degrees else "range_m100_100"
        out.append(mode)
    return tuple(out)


def _normalise_feetech_offset(offset: int, lo: int, hi: int, res: int) -> tuple[int, int, int]:
    """Bring a Feetech offset into ±(res/2 − 1) (Present wraps modulo a turn); adjust the range if clamped."""
    half = res // 2
    off = (offset + half) % res - half
    if off == -half:  # −2048 is not encodable: use −2047, which makes every reading one tick lower
        off = -half + 1
        lo, hi = lo - 1, hi - 1
    return off, lo, hi


def calibrate(
    bus: ServoBus,
    spec: RobotSpec,
    operator: Operator,
    *,
    path: str | os.PathLike[str] | None = None,
    home_after_sweep: bool = False,
    sweep_full_turn: bool = False,
    on_sweep: Callable[[SweepView], None] | None = None,
    max_steps: int | None = None,
    on_status: Callable[[str], None] | None = None,
) -> CalibrationResult:
    """Run LeRobot's current calibration with robocal's fixes and write the JSON file.

    Args:
        bus: The arm's bus.
        spec: The arm.
        operator: Moves the arm and confirms steps.
        path: Where to write the LeRobot JSON (None: do not write).
        home_after_sweep: Sweep first, then choose the homing so the travel is centred on the half turn.
        sweep_full_turn: Also sweep the joints LeRobot forces to 0..4095 (#4583).
        on_sweep: Called after each reading of the sweep (live table).
        max_steps: Stop the sweep after this many readings (None: until the operator finishes).
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
    if path is not None:
        # refuse an impossible output (read-only folder, full disk, ...) before any EEPROM write or sweep
        check_output_path(path, "cannot write", size_hint=1024, create_dirs=True)
    ids = [m.motor_id for m in spec.motors]
    names = [m.name for m in spec.motors]
    res = {m.name: bus.resolution(m.motor_id) for m in spec.motors}
    before = read_eeprom(bus, spec)
    notes: list[str] = []
    try:
        _disable_torque(bus, spec)
        if spec.vendor == "feetech":
            clear_phase_bit4(bus, spec)  # multi-turn feedback would break the half-turn homing (#1296)
        for m in spec.motors:
            bus.write("Operating_Mode", m.motor_id, spec.operating_mode)
            if spec.vendor == "dynamixel":
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
            if spec.vendor == "feetech" and mid[m.motor_id] % res[m.name] == res[m.name] - 1:
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
                    SweepView(
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
                offset = base + shift if spec.vendor == "feetech" else base - shift
            else:
                offset, rmin, rmax = base, lo, hi
            if spec.vendor == "feetech":
                offset, rmin, rmax = _normalise_feetech_offset(offset, rmin, rmax, r)
            dm = 1 if (spec.vendor == "dynamixel" and m.name in spec.inverted) else 0
            cals[m.name] = MotorCalibration(m.motor_id, dm, offset, rmin, rmax)
        for m in spec.motors:
            if m.name not in cals:  # full-turn joint not swept: LeRobot forces 0..res-1
                dm = 1 if (spec.vendor == "dynamixel" and m.name in spec.inverted) else 0
                cals[m.name] = MotorCalibration(m.motor_id, dm, offsets[m.name], 0, res[m.name] - 1)
        ordered = {n: cals[n] for n in names}
        _write_plan(bus, spec, _restore_plan(bus, spec, ordered))
        written = None
        if path is not None:
            try:
                written = write_current(path, ordered)
            except CalibError as exc:
                raise CalibrationNotSavedError(str(exc), ordered) from None
    except BaseException as exc:
        _reraise_after_rollback(exc, _rollback(bus, spec, before, on_status))
        raise
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
    if spec.vendor == "dynamixel":
        on = [m.name for m in spec.motors if bus.read("Torque_Enable", m.motor_id) != 0]
        if on:
            raise UsageError(
                f"To run calibration, the torque must be disabled on all motors (enabled on {', '.join(on)})."
            )
    if path is not None:
        check_output_path(path, "cannot write", size_hint=1024, create_dirs=True)
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


def _restore_plan(
    bus: ServoBus, spec: RobotSpec, cals: Mapping[str, MotorCalibration]
) -> list[tuple[str, str, int, int]]:
    """(motor, register, id, value) writes of a calibration, each checked to fit its register (no bus I/O)."""
    missing = [m.name for m in spec.motors if m.name not in cals]
    if missing:
        raise InvalidCalibrationError(f"calibration has no entry for motor(s) {', '.join(missing)}")
    plan: list[tuple[str, str, int, int]] = []
    for m in spec.motors:
        c = cals[m.name]
        if spec.vendor == "dynamixel":
            plan.append((m.name, "Drive_Mode", m.motor_id, c.drive_mode))
        if bus.has_register(m.motor_id, "Homing_Offset"):
            plan.append((m.name, "Homing_Offset", m.motor_id, c.homing_offset))
        plan.append((m.name, "Min_Position_Limit", m.motor_id, c.range_min))
        plan.append((m.name, "Max_Position_Limit", m.motor_id, c.range_max))
    for name, register, motor_id, value in plan:  # every value must fit before anything is written
        try:
            bus.check_write(register, motor_id, value)
        except CalibError as exc:
            raise type(exc)(f"motor {name!r}: {register}: {exc}") from None
    return plan


def _write_plan(bus: ServoBus, spec: RobotSpec, plan: Sequence[tuple[str, str, int, int]]) -> None:
    _disable_torque(bus, spec)
    for _name, register, motor_id, value in plan:
        bus.write(register, motor_id, value)


def restore(
    bus: ServoBus,
    spec: RobotSpec,
    cals: Mapping[str, MotorCalibration],
    *,
    on_status: Callable[[str], None] | None = None,
) -> None:
    """Write a calibration to the motors, all or nothing: Homing_Offset, limits and (Dynamixel) Drive_Mode.

    Every value is checked to fit its register before anything is sent; then the registers about to be written
    are read (the snapshot), torque is disabled (EEPROM writes) and the calibration is written. On a device
    error or Ctrl-C midway the snapshot is written back to every motor that still answers, so the motors are
    left as they were (torque stays off); the error then says so, or names the motors that could not be
    restored. LeRobot's Dynamixel ``write_calibration`` omits Drive_Mode, so a restored Koch leader stayed
    uncalibrated; robocal writes it.

    Raises:
        InvalidCalibrationError: A motor is missing from ``cals`` or a value does not fit (nothing sent).
        DeviceError: Bus failure (snapshot written back; the message says what was restored).
        KeyboardInterrupt: Re-raised after the snapshot was written back (argument: motors not restored).
    """
    plan = _restore_plan(bus, spec, cals)
    before = read_eeprom(bus, spec)
    try:
        _write_plan(bus, spec, plan)
    except BaseException as exc:
        _reraise_after_rollback(exc, _rollback(bus, spec, before, on_status))
        raise


@dataclass(frozen=True)
class Difference:
    """One EEPROM value that differs from the calibration file."""

    motor: str
    motor_id: int
    field: str
    file_value: int
    motor_value: int

    def __str__(self) -> str:
        return (
            f"motor {self.motor!r} (id {self.motor_id}): {self.field} is {self.motor_value} on the motor, "
            f"{self.file_value} in the file"
        )


def check(bus: ServoBus, spec: RobotSpec, cals: Mapping[str, MotorCalibration]) -> list[Difference]:
    """Compare the motors' EEPROM with a calibration file, naming each motor and field (#1360).

    Compares ``homing_offset``, ``range_min``, ``range_max``, the id (by ping) and, on Dynamixel, bit 0 of
    ``Drive_Mode`` (other bits are ignored). Feetech drive_mode lives only in the file and is not compared.
    """
    unknown = [n for n in cals if n not in spec.motor_names]
    if unknown:
        raise InvalidCalibrationError(f"calibration names motor(s) {', '.join(unknown)} not on a {spec.name}")
    diffs: list[Difference] = []
    eeprom = read_eeprom(bus, spec)
    for m in spec.motors:
        if m.name not in cals:
            raise InvalidCalibrationError(f"calibration has no entry for motor {m.name!r}")
        c = cals[m.name]
        if c.id != m.motor_id:
            diffs.append(Difference(m.name, m.motor_id, "id", c.id, m.motor_id))
        e = eeprom[m.name]
        pairs = [
            ("homing_offset", "Homing_Offset", c.homing_offset),
            ("range_min", "Min_Position_Limit", c.range_min),
            ("range_max", "Max_Position_Limit", c.range_max),
        ]
        if spec.vendor == "dynamixel":
            pairs.append(("drive_mode", "Drive_Mode", c.drive_mode))
        for fname, reg, fval in pairs:
            if reg not in e:
                continue
            mval = e[reg] & 1 if reg == "Drive_Mode" else e[reg]
            if mval != fval:
                diffs.append(Difference(m.name, m.motor_id, fname, fval, mval))
    return diffs


def legacy_to_current(
    legacy_cal: object, vendor: str, ids: Sequence[int] | None = None
) -> tuple[dict[str, MotorCalibration], list[str]]:
    """Convert a legacy calibration to the current format, keeping each DEGREE joint's zero exactly.

    The current DEGREES zero is the middle of ``range_min..range_max``. robocal picks range 0..4094 (middle
    2047) and the Homing_Offset that makes legacy 0° read 2047: Feetech ``H = −h − 2047`` (wrapped to ±2047),
    Dynamixel ``H = h + 2047`` (Drive_Mode carries the inversion). Remaining difference: LeRobot's DEGREES
    scale is 360/4095 per tick instead of the legacy 360/4096 (0.024 %). LINEAR joints keep
    ``start_pos..end_pos`` as their range.

    Returns:
        The current calibration and warnings (Feetech inverted DEGREE joints: LeRobot's DEGREES ignores
        drive_mode).
    """
    from ..core.lerobot import LegacyCalibration

    if not isinstance(legacy_cal, LegacyCalibration):
        raise UsageError("legacy_to_current needs a LegacyCalibration")
    if vendor not in ("feetech", "dynamixel"):
        raise UsageError(f"vendor {vendor!r}: expected 'feetech' or 'dynamixel'")
    n = len(legacy_cal.motor_names)
    motor_ids = list(ids) if ids is not None else list(range(1, n + 1))
    if len(motor_ids) != n:
        raise UsageError(f"{len(motor_ids)} ids for {n} motors")
    seen: set[int] = set()
    for i in motor_ids:
        if isinstance(i, bool) or not isinstance(i, int) or not 0 <= i <= 253:
            raise UsageError(f"--ids: motor id {i} is outside 0..253")
        if i in seen:
            raise UsageError(f"--ids: motor id {i} is given twice")
        seen.add(i)
    out: dict[str, MotorCalibration] = {}
    warnings: list[str] = []
    for k, name in enumerate(legacy_cal.motor_names):
        h = int(legacy_cal.homing_offset[k])
        dm = int(legacy_cal.drive_mode[k])
        if legacy_cal.calib_mode[k] == "LINEAR":
            start, end = int(legacy_cal.start_pos[k]), int(legacy_cal.end_pos[k])
            lo, hi = sorted((start, end))
            if lo == hi:
                raise InvalidCalibrationError(f"motor {name!r}: LINEAR start_pos equals end_pos ({lo})")
            # legacy percent = (raw − start)/(end − start): 0 % at start_pos. With start > end the percentage
            # falls as the reading rises; Feetech's software drive_mode 1 (100 − n) keeps that exactly.
            lin_dm = 0
            if start > end:
                if vendor == "feetech":
                    lin_dm = 1
                else:
                    warnings.append(
                        f"{name}: legacy LINEAR start_pos {start} > end_pos {end} (0 % at the higher reading); "
                        "RANGE_0_100 on Dynamixel counts from range_min, so this joint's percentage is reversed"
                    )
            offset = 0
            if lo < 0 or hi > 4095:  # legacy Feetech readings were unwrapped past the 0/4095 seam
                if hi - lo >= 4095:
                    raise InvalidCalibrationError(
                        f"motor {name!r}: LINEAR start_pos..end_pos {lo}..{hi} spans {hi - lo} ticks, a full turn "
                        "or more of a 4096-tick servo; no range of one turn holds it (recalibrate this motor)"
                    )
                shift, new_lo, new_hi = centre_homing(lo, hi, resolution=4096)
                if vendor == "feetech":
                    offset, new_lo, new_hi = _normalise_feetech_offset(shift, new_lo, new_hi, 4096)
                else:
                    offset = -shift
                warnings.append(
                    f"{name}: legacy LINEAR range {lo}..{hi} goes beyond one turn of a 4096-tick servo "
                    f"(0..4095); re-homed to homing_offset {offset}, range {new_lo}..{new_hi} (the same travel; "
                    "write it to the motor with `robocal lerobot calibrate --use-file`)"
                )
                lo, hi = new_lo, new_hi
            out[name] = MotorCalibration(motor_ids[k], lin_dm, offset, lo, hi)
            continue
        if vendor == "feetech":
            offset = (-h - 2047 + 2048) % 4096 - 2048
            if offset == -2048:
                offset = -2047
                warnings.append(f"{name}: offset clamped by one tick")
            if dm:
                warnings.append(
                    f"{name}: inverted (drive_mode 1) but LeRobot's DEGREES ignores drive_mode on Feetech; "
                    "the sign of this joint flips"
                )
        else:
            offset = h + 2047
        out[name] = MotorCalibration(motor_ids[k], dm, offset, 0, 4094)
    return out, warnings


def export_joint_map(
    spec: RobotSpec,
    cals: Mapping[str, MotorCalibration],
    *,
    signs: Mapping[str, int] | None = None,
    offsets_deg: Mapping[str, float] | None = None,
    compat: str = "lerobot",
    modes: Sequence[str] | None = None,
    convention: str = "lerobot",
) -> tuple[RobotCalibration, list[str]]:
    """Exact canonical joint map ``q_urdf = sign·q_lerobot + offset`` of the DEGREES joints (#4442).

    LeRobot DEGREES: ``q = (present − mid)·360/4095`` (``convention="lerobot"``) or ``·360/4096`` with
    drive_mode (``"physical"``), ``mid = (range_min + range_max)/2``. Canonical form
    ``q_rad = d·k·(present − h)`` with ``d = sign·(−1 if physical and drive_mode else 1)``, ``k = 2π/4095``
    (or ``2π/4096``) rad/tick and ``h = mid − offset_rad/(d·k)``. ``present`` is the Present_Position register
    (EEPROM homing applied). ``compat`` only changes rounding to whole ticks, which a joint map does not do, so
    it does not change the map (it is still checked).

    ``modes`` is the norm mode per motor in bus order (default: the robot's, see :func:`norm_modes`).

    Returns:
        The joint map (radians) of the DEGREES motors and the names of the skipped (range-mode) motors.
    """
    from ..core.lerobot import parse_compat, parse_convention

    parse_compat(compat, "compat")
    physical = parse_convention(convention, "convention") == "physical"
    signs = dict(signs or {})
    offsets_deg = dict(offsets_deg or {})
    unknown = sorted((set(signs) | set(offsets_deg)) - set(spec.motor_names))
    if unknown:
        raise UsageError(f"--sign/--offset name unknown motor(s) {', '.join(unknown)}")
    for name, value in signs.items():
        if value not in (-1, 1):
            raise UsageError(f"--sign {name}={value}: expected -1 or 1")
    mode_of = dict(zip(spec.motor_names, modes if modes is not None else norm_modes(spec), strict=True))
    names, dirs, homes, scales, skipped = [], [], [], [], []
    for m in spec.motors:
        if m.name not in cals:
            raise InvalidCalibrationError(f"calibration has no entry for motor {m.name!r}")
        if mode_of[m.name] != "degrees":
            skipped.append(m.name)
            continue
        c = cals[m.name]
        s = signs.get(m.name, 1)
        ticks = 4096 if physical else 4095
        d = s * (-1 if (physical and c.drive_mode and spec.vendor == "feetech") else 1)
        k = 2 * math.pi / ticks
        mid = (c.range_min + c.range_max) / 2
        off_rad = math.radians(offsets_deg.get(m.name, 0.0))
        names.append(m.name)
        dirs.append(float(d))
        homes.append(mid - off_rad / (d * k))
        scales.append(k)
    if not names:
        raise InvalidCalibrationError(f"{spec.name}: no DEGREES motors to export")
    return RobotCalibration(names, dirs, homes, scales), skipped
