"""The one guard of every command that can move a motor or change a register (issue 26).

:class:`MotionGuard` is entered before the first write to a bus and owns the motors' safe state until it is left:

- SIGINT, SIGTERM, SIGHUP and SIGQUIT raise :class:`~robocal.errors.SignalInterrupt` (a ``KeyboardInterrupt``
  whose exit code is ``128 + signal``) — never inside a packet exchange (:mod:`robocal.backends.bus_transaction`
  holds it until the exchange is complete, so the port stays usable for the clean-up);
- on any exception leaving the block (a signal, a device fault, a read that came too late, a bug) every motor is
  made limp first (the backend's ``limp``), then the registers of the snapshot are written back and read back
  (the backend's ``restore``), and the exception is re-raised with one clause saying what was restored and what
  was not; signals that arrive meanwhile are counted and shown, never allowed to cut the restore short;
- the snapshot (:meth:`MotionGuard.snapshot`) is kept in robocal's state folder
  (:mod:`robocal.workflows.motion.snapshot`) while the registers may differ from it; it is removed when the run
  ends cleanly or everything was restored, so the next command on that bus can offer to restore what was left.

Signals reach the main thread only if no other thread takes them: robocal's helper threads (a stdin reader, the
keep-alive of CAN motors, a viewer) are started with :func:`start_signal_free`, which blocks the guarded signals in
them (from :mod:`robocal.backends.bus_transaction`).

The bus-specific parts come from the caller as callables: ``limp`` (torque off on every motor of the bus, never
raises; returns the motors it could not confirm limp), ``restore`` (write a snapshot back, check it, report),
and optional ``arm``/``disarm`` hooks (a host-loss watchdog).
"""

from __future__ import annotations

import contextlib
import signal
import threading
from collections.abc import Callable, Iterator, Mapping, Sequence
from types import FrameType, TracebackType
from typing import Protocol, TypeVar

from ...backends.bus_transaction import HANDLED_SIGNALS, raise_now_or_after, start_signal_free
from ...errors import CalibError, SignalInterrupt
from .snapshot import SnapshotStore

__all__ = [
    "GUARDED_SIGNALS",
    "MotionGuard",
    "RestoreReport",
    "reraise_with_note",
    "signal_name",
    "start_signal_free",
]

T = TypeVar("T")

GUARDED_SIGNALS: tuple[signal.Signals, ...] = HANDLED_SIGNALS
"""The signals a guarded command turns into a safe ending (Ctrl-C, kill, a closed terminal, Ctrl-\\)."""


def signal_name(signum: int) -> str:
    """``Ctrl-C`` for SIGINT, else the signal's name (``SIGTERM``)."""
    if signum == signal.SIGINT:
        return "Ctrl-C"
    try:
        return signal.Signals(signum).name
    except ValueError:
        return f"signal {signum}"


class RestoreReport(Protocol):
    """What a restore achieved (e.g. :class:`robocal.workflows.lerobot.eeprom.RollbackReport`)."""

    @property
    def restored(self) -> tuple[str, ...]:
        """Motors whose registers were all written back and read back equal."""
        ...

    @property
    def not_restored(self) -> Mapping[str, tuple[str, ...]]:
        """Motor label → registers not written back (or read back different)."""
        ...

    def summary(self) -> str:
        """One clause: everything restored, or which motors and registers were not."""
        ...


def reraise_with_note(exc: BaseException, note: str, *, always: bool = False) -> None:
    """Re-raise ``exc`` with ``note`` appended to its one message line; other exceptions pass unchanged.

    A :class:`CalibError` keeps its type (so its exit code) and gains ``"; <note>"``; a ``KeyboardInterrupt``
    (and :class:`SignalInterrupt`, which keeps its signal) gets ``note`` as its argument only when something
    was not restored (``always``: in any case), so ``args == ()`` still means "everything restored".
    """
    if isinstance(exc, KeyboardInterrupt):
        if not always:
            return
        if isinstance(exc, SignalInterrupt):
            raise SignalInterrupt(exc.signum, note) from None
        raise KeyboardInterrupt(note) from None
    saved = getattr(exc, "calibration", None)
    if isinstance(exc, CalibError) and saved is not None:  # CalibrationNotSavedError keeps its result
        raise type(exc)(f"{exc}; {note}", saved) from exc
    if isinstance(exc, CalibError):
        raise type(exc)(f"{exc}; {note}") from exc


class MotionGuard:
    """Owns the safe state of one bus's motors while a command moves them or changes their registers.

    Use as a context manager around everything from the first write to the last; see the module docstring.

    Args:
        limp: Torque off on every motor of the bus, as fast as the bus allows; never raises. Returns the motors
            it could not confirm limp (they may still hold torque).
        restore: Write a register snapshot back and check it (None: nothing to restore, e.g. a RAM-only job).
        on_status: One status line (the CLI's standard error), e.g. "still restoring…" when a signal comes.
        store: Where the snapshot is kept until the run ends (None: not kept, e.g. an in-process simulator).
        arm: Called on entry (e.g. arm a host-loss watchdog); disarm: called on a clean exit and after a fault.
        what: The registers' name in messages ("EEPROM", "registers").
    """

    def __init__(
        self,
        *,
        limp: Callable[[], Sequence[str]],
        restore: Callable[[Mapping[str, Mapping[str, int]]], RestoreReport] | None = None,
        on_status: Callable[[str], None] | None = None,
        store: SnapshotStore | None = None,
        arm: Callable[[], None] | None = None,
        disarm: Callable[[], None] | None = None,
        what: str = "EEPROM",
    ) -> None:
        self._limp, self._restore, self._on_status = limp, restore, on_status
        self._store, self._arm, self._disarm, self._what = store, arm, disarm, what
        self._snapshot: dict[str, dict[str, int]] | None = None
        self._restoring = False
        self._doing = ""
        self._previous: dict[int, object] = {}
        self.deferred: list[int] = []
        """Signals that came while the motors were being restored (they did not cut it short)."""
        self.limp_failed: tuple[str, ...] = ()
        """Motors the last limp could not confirm limp."""
        self._answered = 0  # how many of the deferred signals were raised already (finish_with)
        self._last_report: RestoreReport | None = None
        self._left = False  # a restore left registers changed: the kept snapshot stays

    # ---------------------------------------------------------------------------------------- signals
    def _handler(self, signum: int, frame: FrameType | None) -> None:
        if self._restoring:
            self.deferred.append(signum)
            if self._on_status is not None:
                doing = self._doing or f"restoring the previous {self._what}"
                with contextlib.suppress(Exception):  # never let the message break the restore
                    self._on_status(f"still {doing}; {signal_name(signum)} is ignored until it is done")
            return
        raise_now_or_after(SignalInterrupt(signum))

    def _install(self) -> None:
        if threading.current_thread() is not threading.main_thread():
            return  # only the main thread can own signals; Ctrl-C still raises KeyboardInterrupt there
        for sig in GUARDED_SIGNALS:
            self._previous[sig] = signal.getsignal(sig)
            signal.signal(sig, self._handler)

    def _uninstall(self) -> None:
        for sig, previous in self._previous.items():
            with contextlib.suppress(Exception):
                signal.signal(sig, previous)  # type: ignore[arg-type]
        self._previous.clear()

    @contextlib.contextmanager
    def deferring(self, doing: str = "") -> Iterator[list[int]]:
        """Hold every guarded signal off while the block runs (counted in :attr:`deferred`, shown).

        ``doing``: what the status line says is going on ("writing the calibration file"; default: restoring).
        """
        was, self._restoring = self._restoring, True
        was_doing, self._doing = self._doing, doing
        try:
            yield self.deferred
        finally:
            self._restoring, self._doing = was, was_doing

    def finish_with(self, write: Callable[[], T]) -> T:
        """The run's last step (e.g. the calibration file) with signals held off, then :meth:`resolved`.

        The motors hold what the run meant them to; a signal during ``write`` no longer undoes them: once the
        write is done it is raised (``SignalInterrupt``), so the command ends by that signal and says what was
        written, with the motors and the file agreeing. A write that fails (a full disk) still restores.
        """
        seen = len(self.deferred)
        with self.deferring("writing the result"):
            out = write()
        self.resolved()
        if len(self.deferred) > seen:
            self._answered = len(self.deferred)
            raise SignalInterrupt(self.deferred[seen])
        return out

    # ---------------------------------------------------------------------------------------- life cycle
    def __enter__(self) -> MotionGuard:
        self._install()
        try:
            if self._arm is not None:
                self._arm()
        except BaseException:
            self._uninstall()
            raise
        return self

    def snapshot(self, registers: Mapping[str, Mapping[str, int]], **about: object) -> None:
        """The registers as they were before the first change: restored on a fault, kept on disk meanwhile.

        ``about`` goes into the kept file (port, robot, motor ids…) for the next run's message.
        """
        self._snapshot = {m: dict(r) for m, r in registers.items()}
        if self._store is not None:
            self._store.save(self._snapshot, **about)

    def resolved(self) -> None:
        """The registers hold what the run meant them to (written and checked): nothing to restore any more."""
        self._snapshot = None
        if self._store is not None:
            self._store.remove()

    def restore_now(self) -> RestoreReport | None:
        """Every motor limp, then the snapshot written back (signals held off meanwhile); None: no snapshot."""
        with self.deferring():
            self.limp_failed = tuple(self._limp())
            if self._disarm is not None:
                with contextlib.suppress(Exception):
                    self._disarm()
            if self._snapshot is None or self._restore is None:
                return None
            report = self._restore(self._snapshot)
        self._last_report = report
        if report.not_restored or self.limp_failed:
            self._left = True
        else:
            self.resolved()
        return report

    def __exit__(
        self, exc_type: type[BaseException] | None, exc: BaseException | None, tb: TracebackType | None
    ) -> None:
        try:
            if exc is None:
                if self._disarm is not None:
                    with self.deferring():
                        self._disarm()
                if not self._left:
                    self.resolved()
                self._signal_wins(None, self._last_report)
                return
            report = self.restore_now()
            if not isinstance(exc, KeyboardInterrupt):
                self._signal_wins(exc, report)
            self._reraise(exc, report)
        finally:
            self._uninstall()

    def _signal_wins(self, cause: BaseException | None, report: RestoreReport | None) -> None:
        """Raise the first signal held off while the motors were made limp and restored, if none was raised yet.

        Nothing cuts a restore short, so a signal that comes meanwhile is only counted (:attr:`deferred`); it then
        decides how the command ends: a fault's exception (``cause``) or a run that restored the motors itself
        (:meth:`restore_now`, then a clean exit) ends as interrupted by that signal (exit ``128 + signum``), with the
        same clause about what is restored and what is not, from ``cause``. Before, the signal was dropped: a
        SIGTERM while a failed search was being undone ended with the search's exit code and no word of it.
        """
        held = self.deferred[self._answered :]
        if not held:
            return
        self._answered = len(self.deferred)
        interrupt = SignalInterrupt(int(held[0]))
        try:
            self._reraise(interrupt, report)
        except SignalInterrupt as noted:
            raise noted from cause
        raise interrupt from cause

    def _reraise(self, exc: BaseException, report: RestoreReport | None) -> None:
        """Re-raise ``exc`` with one clause: what is restored, what is not (by name), what to do next."""
        if report is None and not self.limp_failed:
            return
        parts: list[str] = []
        lost = str(getattr(report, "lost", "") or "")
        if report is not None and lost:  # the device is gone: one clause, what is not verified, the next step
            parts.append(report.summary())
            if self._store is not None and self._store.exists():
                parts.append(f"the previous values are kept in {self._store.path}")
            # a signal keeps its exit code, a device error its type (exit 3); a bug stays a bug
            reraise_with_note(exc, "; ".join(parts), always=True)
            return
        if report is not None and report.not_restored and not report.restored:
            regs = sorted({r for rs in report.not_restored.values() for r in rs})
            parts.append(
                f"no motor answered to get its previous {self._what} back ({', '.join(regs)} left changed)"
            )
        elif report is not None:
            parts.append(report.summary())
        left = bool(self.limp_failed) or (report is not None and bool(report.not_restored))
        if self.limp_failed:
            parts.append(
                f"{', '.join(self.limp_failed)} may still hold torque: switch the arm's power off before touching it"
            )
        if left and self._store is not None and self._store.exists():
            parts.append(
                f"the previous values are kept in {self._store.path}; the next robocal command on "
                f"{self._store.port} offers to write them back"
            )
        reraise_with_note(exc, "; ".join(parts), always=left)
