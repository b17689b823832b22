"""The Damiao TIMEOUT a run arms, kept in robocal's state folder until it is put back (issues 31, 26 item 2).

``sweep --auto`` arms every motor's host-loss watchdog (TIMEOUT, register 9, RAM) before it moves and writes the
old value back when the motor goes limp. A run killed with SIGKILL, a power cut of the host or a lost bus leaves it
armed until the motor's next power cycle, and another stack (LeRobot, openarm_can) driving that motor then finds
it stopping itself whenever its host pauses. So, as for the servo arms' EEPROM (:mod:`.snapshot`), the
values before are kept in the state folder from just before the first TIMEOUT write until the last one is put
back (:class:`WatchdogRecord`, one file per bus), and the next ``sweep --auto`` that opens that bus finds it
(:func:`restore_left_armed`): it says which motors a previous run left armed, writes their TIMEOUT back, reads
it back and removes the file once every one is as before.

``sweep --auto --write-zero`` stores zeros in the motors' flash (0xFE), which no write can take back: the stored
zero is the position the motor is at. The same record keeps, from just before the first zero goes to flash until
the calibration file is written, which motors are being re-zeroed and by how much (:meth:`WatchdogRecord.zero`).
A run killed in between leaves it; the next run on that bus says in one ``note:`` which motors have a new zero in
flash and no file (:func:`note_left_zeros`), and carries the entry on until a ``--write-zero`` run writes a file
for those motors.
"""

from __future__ import annotations

import logging
import math
import os
import time
from collections.abc import Mapping
from contextlib import suppress
from dataclasses import dataclass
from typing import Any

from .snapshot import LeftChanged, SnapshotStore, find_left_changed

__all__ = [
    "TIMEOUT_UNIT_S",
    "ZERO_STATES",
    "LeftArmed",
    "WatchdogRecord",
    "bus_key",
    "left_zeros",
    "note_left_zeros",
    "note_left_zeros_on",
    "restore_left_armed",
]

log = logging.getLogger("robocal.notes")

TIMEOUT_UNIT_S = 50e-6
"""One unit of the Damiao TIMEOUT register: 50 µs."""
_REGISTER = "TIMEOUT"
_TIMEOUT_RID = 9
"""Register id of TIMEOUT (``backends.damiao.tables.Register.TIMEOUT``)."""
_ZEROS = "zeros"
"""The record's entry (its ``about``) of the zeros a ``--write-zero`` run is storing: motor → its state."""
ZERO_STATES = ("planned", "storing", "stored", "unchanged", "written")
"""A motor's zero in :meth:`WatchdogRecord.zero`: to be stored; going to flash now (it may be there); in flash; not
stored after all (a signal stopped the zeroing first); in the calibration file written. The last two drop the
entry (``unchanged`` only a ``planned`` one)."""


def bus_key(interface: str, channel: str, options: Mapping[str, Any] | None = None) -> str:
    """The name the state folder keeps a Damiao bus under: ``damiao:<interface>:<channel>[@host:port]``."""
    opts = options or {}
    where = f"@{opts['host']}:{opts.get('port', '')}" if opts.get("host") else ""
    return f"damiao:{interface}:{channel}{where}"


class WatchdogRecord:
    """The TIMEOUT values before a run armed them, for one bus, kept on disk while any is armed.

    :meth:`changed` is the drivers' ``on_watchdog`` hook: called before a TIMEOUT is written (with the value it
    had) and after it was put back (None). :meth:`zero` is their ``on_zero`` hook (``--write-zero``). The file is
    kept while a TIMEOUT is armed or a stored zero is in no written file.

    Args:
        key: The bus (:func:`bus_key`).
        command: The run, as the next run's note names it.
        zeros: The zeros a killed run left (:func:`note_left_zeros`), carried on until a file holds them.
    """

    def __init__(
        self, key: str, command: str = "sweep --auto", zeros: Mapping[str, Mapping[str, Any]] | None = None
    ) -> None:
        self.store = SnapshotStore(key, command)
        self.before: dict[str, dict[str, int]] = {}
        self.zeros: dict[str, dict[str, Any]] = {m: dict(z) for m, z in (zeros or {}).items()}

    def changed(self, motor: str, before_s: float | None) -> None:
        """``motor``'s TIMEOUT is about to be armed (its value before, s) or was put back (None)."""
        if before_s is None:
            if self.before.pop(motor, None) is None:
                return
        else:
            self.before.setdefault(motor, {_REGISTER: round(before_s / TIMEOUT_UNIT_S)})
        self._keep()

    def zero(self, motor: str, state: str, reading_rad: float = 0.0) -> None:
        """``motor``'s zero is now ``state`` (:data:`ZERO_STATES`).

        ``reading_rad``: the motor's reading (its own frame) where the new zero is stored, i.e. how much every
        reading of it drops.

        A zero a killed run left (perhaps) stored stays named until this run stores it again (the amounts add up)
        or a file holds it; ``planned``, ``storing`` and ``unchanged`` never hide it.
        """
        entry = self.zeros.get(motor)
        if state == "written" or (state == "unchanged" and entry is not None and entry["state"] == "planned"):
            if self.zeros.pop(motor, None) is None:
                return
        elif state == "unchanged" or (entry is not None and entry["state"] != "planned" and state != "stored"):
            return  # a zero (perhaps) in flash stays named as it is until this run stores the next one
        else:
            base = float(entry["reading_deg"]) if entry is not None and entry["state"] == "stored" else 0.0
            since = entry["since"] if entry is not None else f"pid {os.getpid()}, {_now()}"
            self.zeros[motor] = {"state": state, "reading_deg": base + math.degrees(reading_rad), "since": since}
        self._keep()

    def _keep(self) -> None:
        """Write the record, or remove it when nothing is armed and no zero is being or was left stored."""
        if not self.before and not self.zeros:
            self.store.remove()
            return
        self.store.save(
            self.before, vendor="damiao", register="TIMEOUT (9), units of 50 us", **{_ZEROS: self.zeros}
        )


@dataclass(frozen=True)
class LeftArmed:
    """What a previous run left armed on a bus and what this run did about it.

    Attributes:
        command: The run that left it (``sweep --auto``), with its pid and time.
        armed: Motor → the TIMEOUT found, s.
        restored: Motors whose TIMEOUT is back as before (read back).
        not_restored: Motors that did not answer or read back another value.
    """

    command: str
    armed: dict[str, float]
    restored: tuple[str, ...]
    not_restored: tuple[str, ...]

    def describe(self) -> str:
        """One line for the person: who left what, and what is done."""
        what = ", ".join(f"{m} ({s:g} s)" for m, s in self.armed.items())
        text = f"{self.command} left the host-loss watchdog (TIMEOUT) armed on {what}"
        if self.restored:
            text += f"; written back as before: {', '.join(self.restored)}"
        if self.not_restored:
            text += (
                f"; not written back: {', '.join(self.not_restored)} (power the motors off and on, which clears "
                "it, or run this command again)"
            )
        return text


def restore_left_armed(bus: Any, key: str) -> LeftArmed | None:
    """Find what a previous run left armed on ``bus`` (kept as ``key``), write it back, say so; None: nothing.

    A kept record whose motors all read back their previous value is removed silently. The bus must allow
    register writes (``allow_motion``); the note goes to the ``robocal.notes`` logger (a ``note:`` line).
    """
    kept = find_left_changed(key)
    if kept is None:
        return None
    armed: dict[str, float] = {}
    restored: list[str] = []
    not_restored: list[str] = []
    for motor, regs in kept.registers.items():
        if _REGISTER not in regs or motor not in getattr(bus, "motors", {}):
            continue
        want = int(regs[_REGISTER])
        try:
            now = round(float(bus.read_register(motor, _TIMEOUT_RID)))
        except Exception:
            not_restored.append(motor)
            continue
        if now == want:
            continue
        armed[motor] = now * TIMEOUT_UNIT_S
        try:
            bus.disarm_watchdog(motor, want * TIMEOUT_UNIT_S)
            ok = round(float(bus.read_register(motor, _TIMEOUT_RID))) == want
        except Exception:
            ok = False
        (restored if ok else not_restored).append(motor)
    if not not_restored and not left_zeros(kept):
        SnapshotStore(key, kept.command).remove()
        with suppress(OSError):
            kept.path.unlink()
    if not armed and not not_restored:
        return None
    left = LeftArmed(
        f"a previous `robocal {kept.command}` (pid {kept.pid}, {kept.time_utc}) on {kept.port}",
        armed,
        tuple(restored),
        tuple(not_restored),
    )
    log.warning("%s", left.describe())
    return left


def _now() -> str:
    return time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime())


def left_zeros(kept: LeftChanged) -> dict[str, dict[str, Any]]:
    """The zeros a kept record names as (perhaps) in flash with no file written: motor → its entry."""
    zeros = kept.about.get(_ZEROS)
    if not isinstance(zeros, dict):
        return {}
    return {
        str(m): dict(z)
        for m, z in zeros.items()
        if isinstance(z, dict) and z.get("state") in ("storing", "stored") and "reading_deg" in z
    }


def note_left_zeros(key: str) -> dict[str, dict[str, Any]]:
    """Say in one ``note:`` what zeros a killed ``--write-zero`` run left in flash on bus ``key``; returns them.

    The returned entries are for the next :class:`WatchdogRecord` of this bus (it carries them on).
    """
    kept = find_left_changed(key)
    zeros = left_zeros(kept) if kept is not None else {}
    if kept is None or not zeros:
        return {}
    stored = [m for m, z in zeros.items() if z["state"] == "stored"]
    maybe = [m for m, z in zeros.items() if z["state"] == "storing"]

    def each(names: list[str]) -> str:
        return ", ".join(f"{m} (readings {-float(zeros[m]['reading_deg']):+.2f}°)" for m in names)

    since = min(str(z.get("since", "")) for z in zeros.values())
    what = []
    if stored:
        what.append(f"stored a new zero in flash on {each(stored)}")
    if maybe:
        what.append(f"was storing one on {each(maybe)} (it may be in flash)")
    log.warning(
        "a previous `robocal sweep --auto --write-zero` (%s) on %s %s but wrote no calibration file for them; "
        "run `robocal sweep --auto --write-zero` again to write it (calibration files of other stacks made before "
        "read these joints off by that much)",
        since,
        kept.port,
        " and ".join(what),
    )
    return zeros


def note_left_zeros_on(spec: Any) -> dict[str, dict[str, dict[str, Any]]]:
    """:func:`note_left_zeros` for every bus of a ``can:`` source, before it is opened; channel → what it returned."""
    options = {k: v for k, v in spec.options.items() if k in ("host", "port")}
    return {channel: note_left_zeros(bus_key(spec.interface, channel, options)) for channel in spec.channels}
