"""The enabled Damiao motors of a run stay alive while one exchange waits long, and only then (issue 31 item 1).

On the wall clock the held motors get their last command from a keep-alive thread of their own, so a searched
joint whose replies take the whole reply wait (``$ROBOCAL_REPLY_TIMEOUT_MS=500``) no longer starves their 0.5 s
TIMEOUT; the watchdog armed is over twice the reply wait (``watchdog_for``), a wait that needs more than 2 s is
refused before anything is sent; and a host whose loop stops (held up, killed, cut off) still lets every motor's
TIMEOUT stop it. Judged by the simulated motors (state, TIMEOUT register, when it tripped).
"""

from __future__ import annotations

import math
import threading
import time
from collections.abc import Iterator

import pytest

pytest.importorskip("can")

from robocal.backends import REPLY_TIMEOUT_ENV
from robocal.backends.clock import MonotonicClock
from robocal.backends.damiao.bus import DamiaoBus
from robocal.backends.damiao.joint_driver import DamiaoJointDriver
from robocal.backends.damiao.openarm import SimOpenArm
from robocal.backends.damiao.sim import TIMEOUT_UNIT_S
from robocal.backends.damiao.tables import Register, State
from robocal.backends.mit_keepalive import peers_of, watchdog_for
from robocal.errors import UsageError

HANG_GUARD_S = 60.0


def test_the_watchdog_is_over_twice_the_reply_wait_and_a_longer_wait_is_refused() -> None:
    assert watchdog_for(0.0) == 0.5 and watchdog_for(0.1) == 0.5 and watchdog_for(0.2) == 0.5
    assert watchdog_for(0.5) == 1.1  # ROBOCAL_REPLY_TIMEOUT_MS=500
    assert watchdog_for(0.9) == 1.9 and watchdog_for(0.95) == 2.0
    for wait in (0.0, 0.1, 0.2, 0.37, 0.5, 0.9, 0.95):
        assert watchdog_for(wait) > 2 * wait
    with pytest.raises(UsageError, match=r"reply wait of 0\.96 s .* over twice as long \(1\.92 s\).* at most 2 s.*"
                       r"ROBOCAL_REPLY_TIMEOUT_MS to 950 or less"):
        watchdog_for(0.96)


@pytest.fixture
def realtime_arm() -> Iterator[SimOpenArm]:
    arm = SimOpenArm(f"oa-keepalive-{id(object())}", seed=2, realtime=True).start()
    yield arm
    arm.stop()


def _bus(arm: SimOpenArm) -> DamiaoBus:
    return DamiaoBus(arm.channel, arm.motor_specs(), interface="virtual", allow_motion=True)


def test_a_reply_wait_needing_a_watchdog_over_2_s_is_refused_before_anything_is_sent(
    realtime_arm: SimOpenArm, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setenv(REPLY_TIMEOUT_ENV, "1000")
    with _bus(realtime_arm) as bus:
        before = dict(realtime_arm.motors["gripper"].requests)
        with pytest.raises(UsageError, match=r"reply wait of 1 s .* set ROBOCAL_REPLY_TIMEOUT_MS to 950 or less"):
            DamiaoJointDriver(bus, "gripper", 1, 0.75, math.radians(3), MonotonicClock())
        assert realtime_arm.motors["gripper"].requests == before  # nothing sent
        assert realtime_arm.motors["gripper"].ram[Register.TIMEOUT] == 0


def _wait_for(cond: object, what: str) -> None:
    deadline = time.monotonic() + HANG_GUARD_S
    while not cond():  # type: ignore[operator]
        assert time.monotonic() < deadline, f"hang guard: {what}"
        time.sleep(0.02)


@pytest.mark.slow
def test_held_motors_stay_on_while_the_searched_joints_replies_take_the_whole_wait_then_a_silent_host_stops_them(
    realtime_arm: SimOpenArm, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setenv(REPLY_TIMEOUT_ENV, "500")
    arm = realtime_arm
    clock = MonotonicClock()
    hog_stop = threading.Event()

    def hog() -> None:  # a busy sibling thread: the host's threads share the interpreter with it
        while not hog_stop.is_set():
            sum(range(2000))

    with _bus(arm) as bus:
        assert bus.timeout_s == 0.5
        searched = DamiaoJointDriver(bus, "gripper", 1, 0.75, math.radians(3), clock)
        held = [DamiaoJointDriver(bus, n, 1, 0.75, math.radians(3), clock) for n in ("joint_7", "joint_6")]
        assert searched.watchdog_s == 1.1
        for d in (searched, *held):
            assert d.read().ok
        for name in ("gripper", "joint_7", "joint_6"):
            m = arm.motors[name]
            assert m.enabled and m.ram[Register.TIMEOUT] == round(1.1 / TIMEOUT_UNIT_S)
        hogger = threading.Thread(target=hog, daemon=True)
        hogger.start()
        try:
            arm.silence("gripper")  # every exchange of the searched joint now waits the whole 0.5 s
            t0 = time.monotonic()
            lost = 0
            while time.monotonic() - t0 < 3.0:
                s = searched.read()
                lost += not s.ok
            assert lost >= 3
            for name in ("joint_7", "joint_6"):
                m = arm.motors[name]
                assert m.enabled and m.state == State.ENABLED and m.lost_comm_at_s == [], name
            run = peers_of(clock, create=False)
            assert run is not None and run.thread is not None and run.thread.sent > 0
            # the host's loop stops (held up / gone): the keep-alive stops too, and every TIMEOUT acts
            _wait_for(lambda: all(not arm.motors[n].enabled for n in ("joint_7", "joint_6")), "held motors limp")
        finally:
            hog_stop.set()
        for name in ("joint_7", "joint_6"):
            m = arm.motors[name]
            assert m.state == State.LOST_COMM and len(m.lost_comm_at_s) == 1
            assert m.last_rx_s is not None
            assert m.lost_comm_at_s[0] - m.last_rx_s == pytest.approx(1.1, abs=1e-6)  # the watchdog armed
        arm.silence("gripper", False)
        for d in (searched, *held):
            d.limp()
        assert peers_of(clock, create=False) is None  # the run's keep-alive is gone with its last motor
        assert [arm.motors[n].ram[Register.TIMEOUT] for n in ("gripper", "joint_7", "joint_6")] == [0, 0, 0]
