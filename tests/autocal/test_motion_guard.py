"""The motion guard's contract with fake bus callables (issue 26): the order of limp, disarm and restore, signals
held off while restoring, the kept snapshot's life, the exception's one added clause."""

from __future__ import annotations

import os
import signal
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path

import pytest

from robocal.errors import DeviceError, SignalInterrupt
from robocal.workflows.motion.guard import MotionGuard
from robocal.workflows.motion.snapshot import SnapshotStore, find_left_changed


@dataclass
class _Report:
    restored: tuple[str, ...] = ("a",)
    not_restored: dict[str, tuple[str, ...]] = field(default_factory=dict)

    def summary(self) -> str:
        return "previous EEPROM values written back" if not self.not_restored else "could not write b back"


def _guard(calls: list[str], store: SnapshotStore | None = None, report: _Report | None = None) -> MotionGuard:
    def restore(snap: Mapping[str, Mapping[str, int]]) -> _Report:
        calls.append(f"restore {dict(snap)}")
        return report or _Report()

    def limp() -> list[str]:
        calls.append("limp")
        return []

    return MotionGuard(
        limp=limp, restore=restore, store=store,
        arm=lambda: calls.append("arm"), disarm=lambda: calls.append("disarm"),
    )  # fmt: skip


def test_a_clean_run_arms_disarms_and_keeps_nothing(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("XDG_STATE_HOME", str(tmp_path))
    calls: list[str] = []
    store = SnapshotStore("/dev/ttyFAKE0", "test")
    with _guard(calls, store) as guard:
        guard.snapshot({"a": {"Homing_Offset": 5}})
        assert store.exists() and find_left_changed("/dev/ttyFAKE0") is not None
    assert calls == ["arm", "disarm"]
    assert not store.exists()


def test_a_fault_limps_first_then_disarms_then_restores_and_says_so(tmp_path: Path) -> None:
    calls: list[str] = []
    with pytest.raises(DeviceError) as info, _guard(calls) as guard:
        guard.snapshot({"a": {"Homing_Offset": 5}})
        raise DeviceError("/dev/x: gone")
    assert calls == ["arm", "limp", "disarm", "restore {'a': {'Homing_Offset': 5}}"]
    assert str(info.value) == "/dev/x: gone; previous EEPROM values written back"


def test_signals_during_the_restore_are_held_off_and_counted(tmp_path: Path) -> None:
    calls: list[str] = []
    seen: list[str] = []

    def restore(snap: Mapping[str, Mapping[str, int]]) -> _Report:
        os.kill(os.getpid(), signal.SIGTERM)  # a second and third signal while writing back
        os.kill(os.getpid(), signal.SIGINT)
        calls.append("restored")
        return _Report()

    guard = MotionGuard(limp=lambda: [], restore=restore, on_status=seen.append)
    with pytest.raises(SignalInterrupt) as info, guard:
        guard.snapshot({"a": {"Lock": 1}})
        os.kill(os.getpid(), signal.SIGHUP)  # the first: raised here
        pytest.fail("the signal did not interrupt")
    assert info.value.signum == signal.SIGHUP and info.value.exit_code == 129 and info.value.args == ()
    assert calls == ["restored"] and guard.deferred == [signal.SIGTERM, signal.SIGINT]
    assert seen == [
        "still restoring the previous EEPROM; SIGTERM is ignored until it is done",
        "still restoring the previous EEPROM; Ctrl-C is ignored until it is done",
    ]
    assert signal.getsignal(signal.SIGTERM) is not guard._handler  # handlers put back


def test_what_could_not_be_restored_is_kept_and_named(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("XDG_STATE_HOME", str(tmp_path))
    store = SnapshotStore("/dev/ttyFAKE1", "test")
    calls: list[str] = []
    bad = _Report(restored=(), not_restored={"motor 'b' (id 2)": ("Homing_Offset", "Lock")})
    guard = MotionGuard(
        limp=lambda: ["b (id 2)"], restore=lambda snap: bad, store=store, disarm=lambda: calls.append("disarm")
    )
    with pytest.raises(KeyboardInterrupt) as info, guard:
        guard.snapshot({"b": {"Homing_Offset": 7, "Lock": 1}})
        raise KeyboardInterrupt
    assert str(info.value) == (
        "no motor answered to get its previous EEPROM back (Homing_Offset, Lock left changed); b (id 2) may still "
        f"hold torque: switch the arm's power off before touching it; the previous values are kept in {store.path}; "
        "the next robocal command on /dev/ttyFAKE1 offers to write them back"
    )
    kept = find_left_changed("/dev/ttyFAKE1")
    assert kept is not None and kept.registers == {"b": {"Homing_Offset": 7, "Lock": 1}} and kept.command == "test"


def test_a_signal_held_off_while_a_fault_is_undone_ends_the_command_as_that_signal() -> None:
    """The fault's exception stays the cause; the exit code is the signal's (issue 26: no signal is dropped)."""
    calls: list[str] = []

    def limp() -> list[str]:
        os.kill(os.getpid(), signal.SIGTERM)  # kill while the motors are being made limp after the fault
        calls.append("limp")
        return []

    guard = MotionGuard(limp=limp, restore=lambda snap: _Report())
    with pytest.raises(SignalInterrupt) as info, guard:
        guard.snapshot({"a": {"Homing_Offset": 5}})
        raise DeviceError("/dev/x: no reply")
    assert info.value.signum == signal.SIGTERM and info.value.exit_code == 143 and info.value.args == ()
    assert isinstance(info.value.__cause__, DeviceError) and calls == ["limp"]


def test_a_signal_held_off_by_an_explicit_restore_or_the_last_disarm_is_raised_as_the_guard_ends(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setenv("XDG_STATE_HOME", str(tmp_path))

    def restore(snap: Mapping[str, Mapping[str, int]]) -> _Report:
        os.kill(os.getpid(), signal.SIGINT)  # Ctrl-C while a failed search's registers go back
        return _Report()

    guard = MotionGuard(limp=lambda: [], restore=restore)
    with pytest.raises(SignalInterrupt) as info, guard:
        guard.snapshot({"a": {"Lock": 1}})
        assert guard.restore_now() is not None  # the run undoes its own changes, then leaves the block
    assert info.value.signum == signal.SIGINT and info.value.exit_code == 130

    store = SnapshotStore("/dev/ttyFAKE9", "test")
    guard = MotionGuard(limp=lambda: [], store=store, disarm=lambda: os.kill(os.getpid(), signal.SIGHUP))
    with pytest.raises(SignalInterrupt) as info, guard:
        guard.snapshot({"a": {"Lock": 1}})
    assert info.value.signum == signal.SIGHUP and not store.exists()  # the run had finished: nothing to keep


def test_a_signal_finish_with_raised_is_not_raised_twice() -> None:
    guard = MotionGuard(limp=lambda: [])

    def write() -> str:
        os.kill(os.getpid(), signal.SIGTERM)
        return "written"

    try:
        # a caller that takes finish_with's interruption itself: leaving the guard raises it no more
        with guard, pytest.raises(SignalInterrupt) as info:
            guard.finish_with(write)
    except SignalInterrupt:
        pytest.fail("the signal finish_with raised was raised again as the guard ended")
    assert info.value.signum == signal.SIGTERM and info.value.__cause__ is None and guard.deferred == [15]
