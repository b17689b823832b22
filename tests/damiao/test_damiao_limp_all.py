"""Every enabled Damiao motor's torque goes off at once, whatever another motor's reply does (issues 26, 31).

``limp_all`` first sends each enabled motor its no-torque MIT frame and disable without awaiting a reply, then
confirms each limp. Before, it limped motor after motor, each limp three awaited exchanges (and the state file of
the watchdog put back), so a lost reply of the first motor held the second motor's torque-off back by whole reply
waits (seen in the Damiao fault soak: a held gripper limp 129 ms and 664 ms after SIGTERM). And robocal's helper
threads keep the handled signals blocked, so the kernel hands a signal to the main thread, whose handler makes the
motors limp. Judged by the simulated motors (when each one's torque went off) and the threads' signal masks.
"""

from __future__ import annotations

import math
import signal
import threading
import time
from collections.abc import Iterator
from pathlib import Path

import pytest

pytest.importorskip("can")

from robocal.backends import REPLY_TIMEOUT_ENV
from robocal.backends.bus_transaction import HANDLED_SIGNALS, start_signal_free
from robocal.backends.clock import MonotonicClock
from robocal.backends.damiao.bus import DamiaoBus
from robocal.backends.damiao.joint_driver import DamiaoJointDriver
from robocal.backends.damiao.openarm import SimOpenArm
from robocal.backends.mit_keepalive import peers_of
from robocal.workflows.autocal.model import limp_all


class _Recorder:
    """A driver that notes what it is asked, in order (``quick``: it has ``torque_off_nowait``)."""

    def __init__(self, name: str, log: list[str], *, enabled: bool) -> None:
        self.name, self.log, self.enabled = name, log, enabled

    def limp(self) -> None:
        self.log.append(f"limp {self.name}")


class _QuickRecorder(_Recorder):
    def torque_off_nowait(self) -> None:
        self.log.append(f"nowait {self.name}")
        raise OSError("a lost bus: limp_all goes on")


def test_every_enabled_motor_is_sent_its_torque_off_before_any_limp_waits_for_a_reply() -> None:
    log: list[str] = []
    drivers = [
        _QuickRecorder("parked", log, enabled=False),
        _QuickRecorder("searched", log, enabled=True),
        _Recorder("servo", log, enabled=True),
        _QuickRecorder("held", log, enabled=True),
    ]
    assert limp_all(drivers) == []
    assert log == [
        "nowait searched", "nowait held",  # the enabled MIT motors, at once
        "limp searched", "limp servo", "limp held", "limp parked",  # then each confirmed, the enabled first
    ]  # fmt: skip


@pytest.fixture
def arm() -> Iterator[SimOpenArm]:
    a = SimOpenArm(f"oa-limp-all-{id(object())}", seed=4, realtime=True).start()
    yield a
    a.stop()


def test_a_lost_reply_of_the_first_motor_does_not_hold_back_the_second_motors_torque_off(
    arm: SimOpenArm, monkeypatch: pytest.MonkeyPatch
) -> None:
    """J7 stops answering (every exchange with it waits the whole 0.5 s); the held gripper, limped after it, goes
    off within 0.25 s of ``limp_all`` (before: after J7's three lost exchanges, over 1.5 s)."""
    monkeypatch.setenv(REPLY_TIMEOUT_ENV, "500")
    clock = MonotonicClock()
    with DamiaoBus(arm.channel, arm.motor_specs(), interface="virtual", allow_motion=True) as bus:
        j7, grip = (DamiaoJointDriver(bus, n, 1, 0.75, math.radians(3), clock) for n in ("joint_7", "gripper"))
        for d in (j7, grip):
            assert d.read().ok and d.enabled
        assert arm.motors["gripper"].pushing() and arm.motors["joint_7"].pushing()
        arm.silence("joint_7")
        offs = len(arm.motors["gripper"].torque_off_at)
        t0 = time.monotonic()
        limp_all([j7, grip])  # J7 first: both enabled, the order given
        took_s = time.monotonic() - t0
        grip_off = arm.motors["gripper"].torque_off_at[offs:]
        assert grip_off, "the gripper's torque never went off"
        assert grip_off[0][1] - t0 < 0.25, f"gripper off {grip_off[0][1] - t0:.3f} s after limp_all began"
        assert took_s >= 1.0  # J7's confirmed limp still waited for its (lost) replies, after the gripper was off
        assert not arm.motors["gripper"].enabled
        arm.silence("joint_7", False)
        j7.limp()  # its torque-off frames were lost with it; once it answers, the limp goes through
        assert not arm.motors["joint_7"].enabled
    assert peers_of(clock, create=False) is None


def _blocked_in(native_id: int) -> set[int]:
    """The signals blocked in thread ``native_id`` of this process (Linux ``/proc``)."""
    status = Path(f"/proc/self/task/{native_id}/status").read_text()
    mask = int(next(ln.split()[1] for ln in status.splitlines() if ln.startswith("SigBlk:")), 16)
    return {s for s in range(1, 65) if mask >> (s - 1) & 1}


def test_a_thread_started_signal_free_blocks_the_handled_signals_and_the_caller_keeps_its_mask() -> None:
    seen: list[set[int]] = []
    before = signal.pthread_sigmask(signal.SIG_BLOCK, [])
    thread = start_signal_free(threading.Thread(target=lambda: seen.append(signal.pthread_sigmask(signal.SIG_BLOCK, []))))
    thread.join(30)
    assert seen and {int(s) for s in HANDLED_SIGNALS} <= {int(s) for s in seen[0]}
    assert signal.pthread_sigmask(signal.SIG_BLOCK, []) == before


@pytest.mark.skipif(not Path("/proc/self/task").is_dir(), reason="reads the thread's mask from /proc (Linux)")
def test_the_keepalive_thread_leaves_every_handled_signal_to_the_main_thread(arm: SimOpenArm) -> None:
    """A process-directed SIGTERM taken by the keep-alive thread would be handled only once the main thread's reply
    wait ended (up to the reply timeout later); the thread blocks them, so the kernel hands them to the main one."""
    clock = MonotonicClock()
    with DamiaoBus(arm.channel, arm.motor_specs(), interface="virtual", allow_motion=True) as bus:
        grip = DamiaoJointDriver(bus, "gripper", 1, 0.75, math.radians(3), clock)
        assert grip.read().ok
        run = peers_of(clock, create=False)
        assert run is not None and run.thread is not None and run.thread.alive()
        native_id = run.thread._thread.native_id
        assert native_id is not None
        assert {int(s) for s in HANDLED_SIGNALS} <= _blocked_in(native_id)
        assert not {int(s) for s in HANDLED_SIGNALS} & _blocked_in(threading.main_thread().native_id or 0)
        grip.limp()


class _Zeroing(_QuickRecorder):
    """A motor that stores its zero (``--write-zero``); the first one's store meets a signal."""

    def store_zero(self) -> float:
        from robocal.backends.bus_transaction import raise_now_or_after
        from robocal.errors import SignalInterrupt

        self.log.append(f"store {self.name}")
        if len(self.log) == 1:
            raise_now_or_after(SignalInterrupt(signal.SIGTERM))  # the handler, inside the held window
        return 0.0


class _Section:
    joint_names = ("grip", "j6", "j5")

    def joint(self, name: str) -> object:
        return type("AutoJoint", (), {"speed_rad_s": 0.1, "torque_cap_nm": 0.5})()


def test_a_signal_while_zeros_go_to_flash_stores_no_further_zero_and_the_rest_go_limp_at_once(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """Before, every remaining motor stayed held until its own zero was stored (each a limp and four exchanges
    after the previous one's): over 100 ms after the signal. Now the first store ends the flash writes."""
    import contextlib

    from robocal.backends.bus_transaction import transaction
    from robocal.errors import SignalInterrupt
    from robocal.workflows.autocal import zero

    monkeypatch.setattr(zero, "move_to", lambda *a, **k: None)
    monkeypatch.setattr(zero, "_hold", lambda driver, name, target, cap, periods: target)
    log: list[str] = []
    drivers = {n: _Zeroing(n, log, enabled=True) for n in _Section.joint_names}
    stored: list[dict[str, float]] = []
    with pytest.raises(SignalInterrupt), contextlib.ExitStack() as held:  # the held signal comes out at the end
        stored.append(
            zero.store_zeros(drivers, {"grip": 0.1, "j6": 0.2, "j5": 0.3}, _Section(), max_lag_rad=0.05,  # type: ignore[arg-type]
                             before_store=lambda: held.enter_context(transaction()))
        )  # fmt: skip
    assert stored == [{"grip": 0.0}]  # the caller's file rezeroes only what reached flash
    assert log == ["store grip", "nowait j6", "nowait j5", "limp j6", "limp j5"]


def test_a_signal_during_limp_all_is_handled_once_every_motor_is_limp() -> None:
    """Found by the Damiao soak: SIGINT / SIGHUP just after the file was written met the final ``limp_all``; the
    signal's exception left the gripper's limp before its TIMEOUT was put back (left armed at 0.5 s)."""
    import os

    from robocal.errors import SignalInterrupt

    log: list[str] = []

    class _Signalled(_Recorder):
        def limp(self) -> None:
            os.kill(os.getpid(), signal.SIGHUP)  # the handler would run at the next line
            time.sleep(0.05)
            log.append(f"limp {self.name} (watchdog put back)")

    def handler(signum: int, frame: object) -> None:
        raise SignalInterrupt(signum)

    old = signal.signal(signal.SIGHUP, handler)
    try:
        with pytest.raises(SignalInterrupt):
            limp_all([_Signalled("grip", log, enabled=True), _Recorder("j7", log, enabled=True)])
    finally:
        signal.signal(signal.SIGHUP, old)
    assert log == ["limp grip (watchdog put back)", "limp j7"]


@pytest.mark.timeout(600)
def test_every_motor_is_limp_before_the_calibration_file_is_written(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Found by the Damiao soak: SIGHUP while the file was being written left the held gripper on for 457 ms (an
    fsync, which no signal interrupts, ran first). Without ``--write-zero`` nothing needs the motors once the
    search is over: they are limp before any file is written."""
    from importlib import resources

    import robocal.workflows.sweep.job as job_mod
    from robocal.backends.damiao import openarm as openarm_mod
    from robocal.workflows.autocal.sweep import SweepAutoRequest

    from .openarm_session import openarm_session

    holder: list[dict[str, bool]] = []
    arms: list[SimOpenArm] = []
    original = job_mod.write_sweep_files  # run_sweep_auto imports it from there when it runs

    def noting(*args: object, **kwargs: object) -> object:
        holder.append({n: m.enabled for n, m in arms[0].motors.items()})
        return original(*args, **kwargs)  # type: ignore[arg-type]

    monkeypatch.setattr(job_mod, "write_sweep_files", noting)
    started = openarm_mod.SimOpenArm.start

    def start(self: SimOpenArm) -> SimOpenArm:
        arms.append(self)
        return started(self)

    monkeypatch.setattr(openarm_mod.SimOpenArm, "start", start)
    urdf = Path(str(resources.files("robocal").joinpath("data", "openarm_v10_right.urdf")))
    request = SweepAutoRequest(urdf, "sim:openarm?seed=6", tmp_path / "c.json", robot="openarm_follower_right",
                               joints=("openarm_right_gripper_motor", "openarm_right_joint7"))  # fmt: skip
    with openarm_session(request) as (outcome, _sim):
        assert outcome.out == tmp_path / "c.json"
    assert holder == [dict.fromkeys(holder[0], False)] and len(holder[0]) == 8


def test_a_motor_lost_while_held_at_its_zero_is_a_lost_device_and_no_zero_is_stored(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """Found by the Damiao soak (``--write-zero``, the device lost after the searches): the hold at the zero read
    nothing, its NaN became the next target and ended the run as bad input (``cannot encode nan``, exit 2)."""
    import math

    from robocal.errors import DeviceError
    from robocal.workflows.autocal import zero

    class _Lost(_Zeroing):
        def settle_at(self, target_rad: float, duration_s: float) -> float:
            self.log.append(f"settle {self.name} at {target_rad}")
            return math.nan  # every reading of the hold lost

    monkeypatch.setattr(zero, "move_to", lambda *a, **k: None)
    log: list[str] = []
    drivers = {n: _Lost(n, log, enabled=True) for n in _Section.joint_names}
    with pytest.raises(DeviceError, match=r"^grip: no position reading while holding it at its zero"):
        zero.store_zeros(drivers, {"grip": 0.1, "j6": 0.2, "j5": 0.3}, _Section(), max_lag_rad=0.05)  # type: ignore[arg-type]
    assert log == ["settle grip at 0.1"]  # one hold, no NaN target sent, nothing stored
    assert DeviceError("x").exit_code == 3


def test_zeros_are_moved_to_and_stored_in_the_profiles_order_whatever_the_callers_mapping(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """The joints already at their zero load the next one (a shoulder's deflection depends on the elbow), so the
    order changes the zeros stored. ``sweep --auto --write-zero`` passed a mapping built from a set: its order, and
    a simulated OpenArm's stored joint_2 zero (0.0001° or 0.128°), followed PYTHONHASHSEED (a CI failure)."""
    from robocal.workflows.autocal import zero

    moved: list[str] = []
    monkeypatch.setattr(zero, "move_to", lambda driver, *a, **k: moved.append(driver.name))
    monkeypatch.setattr(zero, "_hold", lambda driver, name, target, cap, periods: target)
    log: list[str] = []
    drivers = {n: _Zeroing(n, log, enabled=True) for n in reversed(_Section.joint_names)}
    log.append("start")  # _Zeroing's first store meets a signal: not in this test
    stored = zero.store_zeros(drivers, {"j5": 0.3, "grip": 0.1, "j6": 0.2}, _Section(), max_lag_rad=0.05)  # type: ignore[arg-type]
    assert moved == ["grip", "j6", "j5"]
    assert log == ["start", "store grip", "store j6", "store j5"] and list(stored) == ["grip", "j6", "j5"]
