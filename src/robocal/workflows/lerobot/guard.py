"""The motion guard of a LeRobot arm's bus: limp every motor, write a register snapshot back (issue 26).

:func:`arm_guard` builds the :class:`~robocal.workflows.motion.guard.MotionGuard` every LeRobot command that writes
to the motors runs under (``calibrate``, ``calibrate --auto``, ``calibrate --use-file``, ``configure``): limp is
``Torque_Enable`` 0 in one SYNC_WRITE and then once per motor, read back; restore writes the snapshot back motor
by motor (:func:`robocal.workflows.lerobot.eeprom._rollback`, which reads it back), after rebooting Dynamixels
whose protection latched.
"""

from __future__ import annotations

import weakref
from collections.abc import Callable, Iterator, Mapping, Sequence
from contextlib import contextmanager, suppress
from dataclasses import dataclass

from ...backends.servo_bus import ServoBus
from ...core.lerobot import RobotSpec
from ...errors import CalibError, DeviceGoneError
from ..motion.guard import MotionGuard
from ..motion.snapshot import LeftChanged, SnapshotStore, find_left_changed
from .eeprom import RollbackReport, _rollback

__all__ = [
    "LeftOver",
    "arm_guard",
    "find_left_over",
    "limp_arm",
    "lost_reason",
    "next_step",
    "restore_left_over",
    "restore_registers",
    "silent_round",
]


_LOST: weakref.WeakKeyDictionary[object, str] = weakref.WeakKeyDictionary()
"""Buses found lost (bus → why): the rest of a clean-up skips the reads and writes that cannot arrive."""


_PORT_FAILED = "the port failed"


def lost_reason(bus: object) -> str | None:
    """Why ``bus`` was given up as lost (its port vanished, or no motor answered a whole round), else None."""
    return _LOST.get(bus)


def _mark_lost(bus: object, why: str) -> None:
    with suppress(TypeError):  # a bus object that takes no weak reference is simply not remembered
        _LOST[bus] = why


@contextmanager
def _one_try(bus: object) -> Iterator[None]:
    """Each packet of the block is sent once (no retries): a round of reads that finds the bus silent ends fast."""
    retries = getattr(bus, "retries", None)
    if isinstance(retries, int):
        bus.retries = 0  # type: ignore[attr-defined]
    try:
        yield
    finally:
        if isinstance(retries, int):
            bus.retries = retries  # type: ignore[attr-defined]


def _read_each(bus: ServoBus, ids: list[int]) -> dict[int, int]:
    """``Torque_Enable`` of each motor that answers (a vanished port raises :class:`DeviceGoneError`)."""
    out: dict[int, int] = {}
    for i in ids:
        try:
            out[i] = bus.read("Torque_Enable", i)
        except DeviceGoneError:
            raise
        except CalibError:
            pass
    return out


LOST_TEXT = "the device is lost (no motor answered a whole round of reads)"


def silent_round(bus: ServoBus, ids: Sequence[int]) -> bool:
    """True when none of ``ids`` answers one round of reads, one try per packet; the bus is then marked lost.

    One SYNC_READ of ``Torque_Enable`` (one reply time), then, where that fails, one read per motor. A port that
    itself failed raises :class:`DeviceGoneError`. Asked after a read failed with all its retries: a bus where
    nothing answers at all is given up at once instead of paying every further read's retries.
    """
    with _one_try(bus):
        try:
            answered = bus.sync_read("Torque_Enable", list(ids))
        except DeviceGoneError:
            raise
        except Exception:  # a silent motor, or a bus without SYNC_READ (Feetech SCS): one read per motor
            answered = _read_each(bus, list(ids))
    if answered:
        return False
    _mark_lost(bus, "no motor answered a whole round of reads")
    return True


def limp_arm(bus: ServoBus, spec: RobotSpec) -> list[str]:
    """Torque off on every motor in one SYNC_WRITE, then once more per motor, then read back; never raises.

    The read-back is one round with one try per packet; motors silent in it are asked again with the bus's
    retries, unless the whole round was silent or the port itself failed: then the bus is lost
    (:func:`lost_reason`) and nothing more is tried (each packet would only wait out its reply time).

    Returns:
        ``"name (id N)"`` of the motors whose ``Torque_Enable`` did not read back 0 or could not be read.
    """
    labels = {m.motor_id: f"{m.name} (id {m.motor_id})" for m in spec.motors}
    ids = [m.motor_id for m in spec.motors]
    if (lost_reason(bus) or "").startswith(_PORT_FAILED):  # nothing can be sent any more
        return list(labels.values())
    try:
        bus.sync_write("Torque_Enable", dict.fromkeys(ids, 0))
        for i in ids:
            try:
                bus.sync_write("Torque_Enable", {i: 0})
            except DeviceGoneError:
                raise
            except CalibError:
                pass
    except DeviceGoneError as exc:
        _mark_lost(bus, f"{_PORT_FAILED}: {exc}")
    except Exception:  # the read-back below tells what the writes achieved
        pass
    if lost_reason(bus) is not None:
        return list(labels.values())
    now: dict[int, int] = {}
    try:
        with _one_try(bus):
            try:  # one SYNC_READ when every motor answers
                now = bus.sync_read("Torque_Enable", ids)
            except DeviceGoneError:
                raise
            except Exception:  # a silent motor, or a bus without SYNC_READ (Feetech SCS): one read per motor
                now = _read_each(bus, ids)
        if not now:
            _mark_lost(bus, "no motor answered a whole round of reads")
            return list(labels.values())
        now.update(_read_each(bus, [i for i in ids if i not in now]))  # an answering bus: retries for the silent
    except DeviceGoneError as exc:
        _mark_lost(bus, f"{_PORT_FAILED}: {exc}")
        return list(labels.values())
    except Exception:  # never raises: the motors not read are reported below
        pass
    return [labels[i] for i in ids if now.get(i, 1) != 0]


def _lost_report(
    spec: RobotSpec, before: Mapping[str, Mapping[str, int]], why: str, next_step: str, on: Sequence[str]
) -> RollbackReport:
    not_restored = {
        f"motor {m.name!r} (id {m.motor_id})": tuple(before[m.name]) for m in spec.motors if before.get(m.name)
    }
    return RollbackReport((), not_restored, lost=why, next_step=next_step, may_hold_torque=tuple(on))


def restore_registers(
    bus: ServoBus,
    spec: RobotSpec,
    before: Mapping[str, Mapping[str, int]],
    on_status: Callable[[str], None] | None,
    next_step: str = "",
) -> RollbackReport:
    """Every motor limp, the watchdogs disarmed, latched Dynamixels rebooted, the snapshot written back (checked).

    A bus found lost (:func:`limp_arm`) is not tried further: the report names every register as not restored,
    with ``next_step`` (what to run once the device is back).
    """
    on = limp_arm(bus, spec)
    why = lost_reason(bus)
    if why is not None:
        return _lost_report(spec, before, why, next_step, on)
    disarm = getattr(bus, "disarm_watchdog", None)  # Dynamixel Bus_Watchdog; Feetech has none
    if disarm is not None:  # first: a tripped Bus_Watchdog refuses the goal registers the snapshot restores
        with suppress(Exception):
            disarm([m.motor_id for m in spec.motors])
    latched = spec.vendor_spec.latched_error_register
    if latched is not None:
        reboot = getattr(bus, "reboot", None)
        for m in spec.motors:
            with suppress(Exception):
                if reboot is not None and bus.sync_read(latched, [m.motor_id])[m.motor_id]:
                    reboot(m.motor_id)
    report = _rollback(bus, spec, before, on_status)
    if report.lost:  # the port failed during the rollback
        _mark_lost(bus, report.lost)
        return RollbackReport(report.restored, report.not_restored, report.deferred_interrupts, report.lost,
                              next_step, tuple(f"{m.name} (id {m.motor_id})" for m in spec.motors))  # fmt: skip
    return report


def next_step(spec: RobotSpec, port: str | None) -> str:
    """What to run once a lost device is back: ``robocal lerobot restore-previous`` (or check the arm by hand)."""
    if port is None:
        return "check the arm's registers before using it"
    return f"reconnect it and run `robocal lerobot restore-previous --robot {spec.name} --port {port}`"


def arm_guard(
    bus: ServoBus,
    spec: RobotSpec,
    *,
    command: str,
    on_status: Callable[[str], None] | None = None,
    snapshot_port: str | None = None,
    arm: Callable[[], None] | None = None,
    disarm: Callable[[], None] | None = None,
) -> MotionGuard:
    """The guard of ``bus`` (``snapshot_port``: keep the snapshot in the state folder under that port's name).

    ``arm`` / ``disarm``: called when the guard is entered and when it is left (cleanly or after the limp), e.g.
    a host-loss watchdog of the motors (Dynamixel ``Bus_Watchdog``).
    """
    return MotionGuard(
        limp=lambda: limp_arm(bus, spec),
        restore=lambda snap: restore_registers(bus, spec, snap, on_status, next_step(spec, snapshot_port)),
        on_status=on_status,
        store=SnapshotStore(snapshot_port, command) if snapshot_port is not None else None,
        arm=arm,
        disarm=disarm,
    )


@dataclass(frozen=True)
class LeftOver:
    """What a previous run left changed on a bus (its kept snapshot, compared with the motors now).

    Attributes:
        kept: The snapshot file the previous run left.
        differing: ``(motor, register, value now, value before)`` for every register that differs.
        torque_on: Motors whose ``Torque_Enable`` reads 1.
        unreadable: Motors that did not answer.
    """

    kept: LeftChanged
    differing: tuple[tuple[str, str, int, int], ...]
    torque_on: tuple[str, ...]
    unreadable: tuple[str, ...]

    def describe(self) -> str:
        """One line: which run, which registers (by motor and name, now → before), which motors hold torque."""
        per: dict[str, list[str]] = {}
        for motor, reg, now, before in self.differing:
            per.setdefault(motor, []).append(f"{reg} {now} (was {before})")
        what = "; ".join(f"{m}: {', '.join(r)}" for m, r in per.items()) or "no register differs"
        text = (
            f"a previous `robocal {self.kept.command}` (pid {self.kept.pid}, {self.kept.time_utc}) on "
            f"{self.kept.port} did not finish: {what}"
        )
        if self.torque_on:
            text += f"; torque on: {', '.join(self.torque_on)}"
        if self.unreadable:
            text += f"; not answering: {', '.join(self.unreadable)}"
        return text


def find_left_over(bus: ServoBus, spec: RobotSpec, port: str) -> LeftOver | None:
    """The registers a previous run left changed on ``port`` (None: nothing kept, or nothing differs any more).

    A kept snapshot whose registers all read back equal is removed (someone restored them, or the run's last
    step did and then the process was killed).
    """
    kept = find_left_changed(port)
    if kept is None:
        return None
    differing: list[tuple[str, str, int, int]] = []
    torque: list[str] = []
    unreadable: list[str] = []
    answered = False
    for k, m in enumerate(spec.motors):
        regs = {r: v for r, v in kept.registers.get(m.name, {}).items() if bus.has_register(m.motor_id, r)}
        try:
            for reg, value in regs.items():
                now = bus.read(reg, m.motor_id)
                answered = True
                if now != value:
                    differing.append((m.name, reg, now, value))
            if bus.read("Torque_Enable", m.motor_id) != 0:
                torque.append(m.name)
            answered = True
        except CalibError as exc:
            rest = [o.motor_id for o in spec.motors[k + 1 :]]
            if isinstance(exc, DeviceGoneError) or (not answered and (not rest or silent_round(bus, rest))):
                # nothing answers: every further read would only wait out its retries (a Koch: ~100 s)
                raise DeviceGoneError(
                    f"{exc}; {LOST_TEXT} before anything was moved or written; a previous run "
                    f"({kept.command}) left registers changed on {port}: reconnect it and run "
                    f"`robocal lerobot restore-previous --robot {spec.name} --port {port}`"
                ) from exc
            unreadable.append(m.name)
    if not differing and not unreadable:
        SnapshotStore(port, kept.command).remove()
        return None
    return LeftOver(kept, tuple(differing), tuple(torque), tuple(unreadable))


def restore_left_over(
    bus: ServoBus, spec: RobotSpec, left: LeftOver, on_status: Callable[[str], None] | None = None
) -> RollbackReport:
    """Every motor limp, the kept values written back and read back; the file removed when all are back."""
    before: dict[str, dict[str, int]] = {}
    for motor, reg, _now, value in left.differing:
        before.setdefault(motor, {})[reg] = value
    report = restore_registers(bus, spec, before, on_status)
    if not report.not_restored:
        SnapshotStore(left.kept.port, left.kept.command).remove()
        with suppress(OSError):
            left.kept.path.unlink()
    return report
