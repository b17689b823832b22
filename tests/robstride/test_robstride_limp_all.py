"""A signal takes every Robstride motor's torque off at once, whatever another motor's replies do (issue 26).

``limp_all`` first sends each enabled MIT-mode motor its torque-off without awaiting a reply, then confirms each
limp (the Damiao path has done so since the soak measured a held gripper limp 664 ms after SIGTERM). The Robstride
driver had no such first frames: a motor that stopped answering held the next motor's stop frame back by its own
limp's reply waits (the zero-torque frame, stop, the torque limit and the CAN timeout put back). Judged on the wire
(a second python-can bus on the channel: when each stop frame was sent) and by the simulated motors' modes.
"""

from __future__ import annotations

import os
import signal
import time

import pytest

pytest.importorskip("can")

from robocal.backends.clock import MonotonicClock
from robocal.backends.robstride.bus import MotorSpec, RobstrideBus
from robocal.backends.robstride.joint_driver import MAX_LAG_RAD, RobstrideJointDriver
from robocal.backends.robstride.protocol import CommType
from robocal.backends.robstride.sim import SimMotor, SimMotorBus
from robocal.core.stop_search import Command
from robocal.errors import SignalInterrupt
from robocal.workflows.autocal.model import limp_all
from robocal.workflows.motion.guard import MotionGuard

LIMP_BOUND_S = 0.1


def _stops(sniffer: object, since: float) -> dict[int, float]:
    """CAN id → when its first stop frame (type 4) was sent after ``since`` (``time.time()``, the sender's stamp)."""
    out: dict[int, float] = {}
    while (msg := sniffer.recv(timeout=0.0)) is not None:  # type: ignore[attr-defined]
        comm, target = msg.arbitration_id >> 24, msg.arbitration_id & 0xFF
        if msg.is_extended_id and comm == CommType.STOP and msg.timestamp >= since:
            out.setdefault(target, msg.timestamp)
    return out


def test_a_signal_takes_the_answering_motors_torque_off_within_100_ms_while_another_is_silent() -> None:
    import can

    channel = f"robocal-rs-limp-{os.getpid()}-{time.monotonic_ns()}"
    motors = [SimMotor(can_id=11 + i, model="rs-05") for i in range(2)]
    specs = [MotorSpec(f"j{i}", 11 + i, "rs-05") for i in range(2)]
    clock = MonotonicClock()
    with (
        SimMotorBus(channel, motors) as sim,
        RobstrideBus(channel, specs, interface="virtual", timeout_s=0.5) as bus,
        can.Bus(interface="virtual", channel=channel) as sniffer,
    ):
        drivers = [RobstrideJointDriver(bus, s.name, 1, 0.4, MAX_LAG_RAD, clock) for s in specs]
        for d in drivers:
            assert d.execute(Command("hold", 0.0, 0.0, 0.4)).ok and d.enabled
        assert [m.mode for m in motors] == [2, 2]  # both in run mode, holding
        sim.silent.add(11)  # j0 stops answering: every exchange with it waits the whole 0.5 s
        t_signal = time.time()
        with pytest.raises(SignalInterrupt), MotionGuard(limp=lambda: limp_all(drivers), what="motor state"):
            signal.raise_signal(signal.SIGTERM)
        took_s = time.time() - t_signal
        stops = _stops(sniffer, t_signal)
        assert 12 in stops and 11 in stops  # the silent motor's stop frame went out too
        assert stops[12] - t_signal < LIMP_BOUND_S, f"j1's stop frame {stops[12] - t_signal:.3f} s after SIGTERM"
        assert took_s >= 1.0  # j0's confirmed limp still waited for its (lost) replies, after j1 was off
        assert motors[1].mode == 0  # the simulator: the answering motor is in reset mode (limp)
        assert motors[1].can_timeout == 0  # its CAN timeout put back
        sim.silent.discard(11)
        drivers[0].limp()  # once it answers again, its limp goes through
        assert motors[0].mode == 0 and motors[0].can_timeout == 0
