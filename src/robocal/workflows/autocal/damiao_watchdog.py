"""The Damiao TIMEOUT a run arms, kept in robocal's state folder until it is put back (issues 31, 26 item 2).

``sweep --auto`` arms every motor's host-loss watchdog (TIMEOUT, register 9, RAM) before it moves and writes the
old value back when the motor goes limp. A run killed with SIGKILL, a power cut of the host or a lost bus leaves it
armed until the motor's next power cycle, and another stack (LeRobot, openarm_can) driving that motor then finds
it stopping itself whenever its host pauses. So, as for the servo arms' EEPROM (:mod:`..motion.snapshot`), the
values before are kept in the state folder from just before the first TIMEOUT write until the last one is put
back (:class:`WatchdogRecord`, one file per bus), and the next ``sweep --auto`` that opens that bus finds it
(:func:`restore_left_armed`): it says which motors a previous run left armed, writes their TIMEOUT back, reads
it back and removes the file once every one is as before.
"""

from __future__ import annotations

import logging
from collections.abc import Mapping
from contextlib import suppress
from dataclasses import dataclass
from typing import Any

from ..motion.snapshot import SnapshotStore, find_left_changed

__all__ = ["TIMEOUT_UNIT_S", "LeftArmed", "WatchdogRecord", "bus_key", "restore_left_armed"]

log = logging.getLogger("robocal.notes")

TIMEOUT_UNIT_S = 50e-6
"""One unit of the Damiao TIMEOUT register: 50 µs."""
_REGISTER = "TIMEOUT"
_TIMEOUT_RID = 9
"""Register id of TIMEOUT (``backends.damiao.tables.Register.TIMEOUT``)."""


def bus_key(interface: str, channel: str, options: Mapping[str, Any] | None = None) -> str:
    """The name the state folder keeps a Damiao bus under: ``damiao:<interface>:<channel>[@host:port]``."""
    opts = options or {}
    where = f"@{opts['host']}:{opts.get('port', '')}" if opts.get("host") else ""
    return f"damiao:{interface}:{channel}{where}"


class WatchdogRecord:
    """The TIMEOUT values before a run armed them, for one bus, kept on disk while any is armed.

    :meth:`changed` is the drivers' ``on_watchdog`` hook: called before a TIMEOUT is written (with the value it
    had) and after it was put back (None).
    """

    def __init__(self, key: str, command: str = "sweep --auto") -> None:
        self.store = SnapshotStore(key, command)
        self.before: dict[str, dict[str, int]] = {}

    def changed(self, motor: str, before_s: float | None) -> None:
        """``motor``'s TIMEOUT is about to be armed (its value before, s) or was put back (None)."""
        if before_s is None:
            if self.before.pop(motor, None) is not None and not self.before:
                self.store.remove()
                return
        else:
            self.before.setdefault(motor, {_REGISTER: round(before_s / TIMEOUT_UNIT_S)})
        if self.before:
            self.store.save(self.before, vendor="damiao", register="TIMEOUT (9), units of 50 us")


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
    if not not_restored:
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
