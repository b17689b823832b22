"""The calibration registers in the motors' EEPROM: snapshot, all-or-nothing restore with rollback, check."""

from __future__ import annotations

import contextlib
import signal
import threading
from collections.abc import Callable, Iterator, Mapping, Sequence
from dataclasses import dataclass

from ...backends.servo_bus import ServoBus
from ...core.lerobot import (
    MotorCalibration,
    RobotSpec,
)
from ...errors import CalibError, DeviceGoneError, InvalidCalibrationError

__all__ = [
    "EEPROM_FIELDS",
    "Difference",
    "RollbackReport",
    "check",
    "read_eeprom",
    "restore",
]


EEPROM_FIELDS = ("Homing_Offset", "Min_Position_Limit", "Max_Position_Limit", "Drive_Mode")

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
        lost: Why the device was given up as lost (its port vanished, or no motor answered a whole round);
            empty when it was not.
        next_step: What to run once a lost device is back (``robocal lerobot restore-previous …``).
        may_hold_torque: ``"name (id N)"`` of the motors whose torque off could not be confirmed (a lost device).
    """

    restored: tuple[str, ...]
    not_restored: dict[str, tuple[str, ...]]
    deferred_interrupts: int = 0
    lost: str = ""
    next_step: str = ""
    may_hold_torque: tuple[str, ...] = ()

    def summary(self) -> str:
        """One clause: everything restored, or exactly which motors and registers were and were not."""
        if self.lost:
            regs = list(dict.fromkeys(r for rs in self.not_restored.values() for r in rs))
            torque = ", ".join(self.may_hold_torque) or "every motor"
            text = (
                f"the device is lost ({self.lost}); not verified: {torque} may still hold torque (switch the arm's "
                "power off before touching it)"
            )
            if regs:
                text += f", and the previous EEPROM ({', '.join(regs)}) is not restored"
            return text + (f"; {self.next_step}" if self.next_step else "")
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
    lost = ""
    with _defer_sigint(
        on_status
    ) as deferred:  # first: a Ctrl-C while the status line is shown is deferred too
        if on_status is not None:
            on_status("restoring the previous EEPROM of every motor…")
        interrupts = 0
        for m in spec.motors:
            regs = [(f, v) for f, v in before.get(m.name, {}).items() if bus.has_register(m.motor_id, f)]
            regs.sort(key=lambda fv: fv[0] == "Lock")  # the EEPROM lock last, after the EEPROM it guards
            done: list[str] = []
            if lost:  # the port failed: nothing more can arrive
                not_restored[label[m.name]] = tuple(f for f, _v in regs)
                continue
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
                except DeviceGoneError:
                    raise
                except CalibError:
                    now = dict(regs)  # acknowledged writes; the read-back itself failed
                done = [f for f in done if now[f] == dict(regs)[f]]
            except DeviceGoneError as exc:
                lost, done = f"the port failed: {exc}", []  # not read back: not verified
            except CalibError:
                pass
            missing = tuple(f for f, _v in regs if f not in done)
            if missing:
                not_restored[label[m.name]] = missing
            else:
                restored.append(m.name)
    return RollbackReport(tuple(restored), not_restored, deferred[0] + interrupts, lost)

def _disable_torque(bus: ServoBus, spec: RobotSpec) -> None:
    for m in spec.motors:
        bus.write("Torque_Enable", m.motor_id, 0)
        if bus.has_register(m.motor_id, "Lock"):
            bus.write("Lock", m.motor_id, 0)

def calibration_writes(
    bus: ServoBus, spec: RobotSpec, cals: Mapping[str, MotorCalibration]
) -> list[tuple[str, str, int, int]]:
    """(motor, register, id, value): the registers a calibration occupies on the motors of ``spec`` in ``cals``.

    Drive_Mode where the vendor keeps it in the motor, Homing_Offset where the model has one, the two position
    limits; nothing checked, no bus I/O.
    """
    plan: list[tuple[str, str, int, int]] = []
    for m in spec.motors:
        c = cals.get(m.name)
        if c is None:
            continue
        if spec.vendor_spec.drive_mode_in_hardware:
            plan.append((m.name, "Drive_Mode", m.motor_id, c.drive_mode))
        if bus.has_register(m.motor_id, "Homing_Offset"):
            plan.append((m.name, "Homing_Offset", m.motor_id, c.homing_offset))
        plan.append((m.name, "Min_Position_Limit", m.motor_id, c.range_min))
        plan.append((m.name, "Max_Position_Limit", m.motor_id, c.range_max))
    return plan


def _restore_plan(
    bus: ServoBus, spec: RobotSpec, cals: Mapping[str, MotorCalibration]
) -> list[tuple[str, str, int, int]]:
    """(motor, register, id, value) writes of a calibration, each checked to fit its register (no bus I/O)."""
    missing = [m.name for m in spec.motors if m.name not in cals]
    if missing:
        raise InvalidCalibrationError(f"calibration has no entry for motor(s) {', '.join(missing)}")
    plan = calibration_writes(bus, spec, cals)
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
    snapshot_port: str | None = None,
) -> None:
    """Write a calibration to the motors, all or nothing: Homing_Offset, limits and (Dynamixel) Drive_Mode.

    Every value is checked to fit its register before anything is sent; then the registers about to be written
    are read (the snapshot), torque is disabled (EEPROM writes) and the calibration is written. On a device
    error or a signal midway (under :class:`~robocal.workflows.motion.guard.MotionGuard`; ``snapshot_port``: the
    snapshot is kept in robocal's state folder meanwhile) the snapshot is written back to every motor that still answers, so the motors are
    left as they were (torque stays off); the error then says so, or names the motors that could not be
    restored. LeRobot's Dynamixel ``write_calibration`` omits Drive_Mode, so a restored Koch leader stayed
    uncalibrated; robocal writes it.

    Raises:
        InvalidCalibrationError: A motor is missing from ``cals`` or a value does not fit (nothing sent).
        DeviceError: Bus failure (snapshot written back; the message says what was restored).
        KeyboardInterrupt: Re-raised after the snapshot was written back (argument: motors not restored).
    """
    from .guard import arm_guard

    plan = _restore_plan(bus, spec, cals)
    before = read_eeprom(bus, spec)
    guard = arm_guard(
        bus, spec, command="lerobot calibrate --use-file", on_status=on_status, snapshot_port=snapshot_port
    )
    with guard:  # a signal or fault midway: limp, the snapshot written back and checked (motion_guard.py)
        guard.snapshot(before, robot=spec.name)
        _write_plan(bus, spec, plan)

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
        if spec.vendor_spec.drive_mode_in_hardware:
            pairs.append(("drive_mode", "Drive_Mode", c.drive_mode))
        for fname, reg, fval in pairs:
            if reg not in e:
                continue
            mval = e[reg] & 1 if reg == "Drive_Mode" else e[reg]
            if mval != fval:
                diffs.append(Difference(m.name, m.motor_id, fname, fval, mval))
    return diffs
