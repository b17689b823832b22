"""The real-time pacer of a standalone simulator: a host-loss watchdog judges the host's silence, not the
simulator's own stalls (``backends/sim/pacer.py``).

The turns are driven by hand (``tick``), so the wall clock plays no part: what is checked is the rule.
"""

from __future__ import annotations

import contextlib
from collections.abc import Iterator

import pytest

from robocal.backends.damiao.sim import TIMEOUT_UNIT_S, SimDamiaoMotor
from robocal.backends.damiao.tables import State
from robocal.backends.sim.pacer import PACE_S, STALL_S, RealtimePacer, own_stall_s
from robocal.backends.sim.physics import JointPlant, PlantParams, SimClock

TIMEOUT_UNITS = 10000  # 0.5 s, as robocal arms it
ARM_TIMEOUT = f"01005509{TIMEOUT_UNITS & 0xFF:02X}{TIMEOUT_UNITS >> 8:02X}0000"
ENABLE = "FFFFFFFFFFFFFFFC"
HOLD = "7FFF7FF0511997FF"  # an MIT command: hold near 0


def _motor(clock: SimClock) -> SimDamiaoMotor:
    params = PlantParams(inertia_kgm2=0.002, stop_lower_rad=-1.0, stop_upper_rad=1.0, counts_per_rev=16384)
    return SimDamiaoMotor(1, 0x11, "DM4310", plant=JointPlant(params, q0_rad=0.0), clock=clock, zero_abs_rad=0.0)


@contextlib.contextmanager
def _unlocked() -> Iterator[None]:
    yield


def _armed() -> tuple[SimClock, SimDamiaoMotor, RealtimePacer, float]:
    clock = SimClock()
    motor = _motor(clock)
    for frame in (ARM_TIMEOUT, ENABLE, HOLD):
        motor.handle(0x7FF if frame == ARM_TIMEOUT else 0x001, bytes.fromhex(frame))
    assert motor.state == State.ENABLED and pytest.approx(0.5) == TIMEOUT_UNITS * TIMEOUT_UNIT_S
    return clock, motor, RealtimePacer(clock, [motor], _unlocked), clock.now()


def test_a_host_silent_while_the_simulator_runs_trips_the_timeout_on_time() -> None:
    _clock, motor, pacer, t0 = _armed()
    last_rx = motor.last_rx_s
    assert last_rx is not None
    for turn in range(1, int(0.6 / PACE_S) + 1):  # 0.6 s of turns every 5 ms, no frame from the host
        pacer.tick(turn * PACE_S, t0)
    assert motor.state == State.LOST_COMM
    assert motor.lost_comm_at_s == [pytest.approx(last_rx + 0.5)]
    assert pacer.stalls_s == []


def test_the_simulators_own_stall_is_not_the_hosts_silence() -> None:
    clock, motor, pacer, t0 = _armed()
    pacer.tick(PACE_S, t0)
    # the simulator's process was held up 0.8 s (the host's frames meanwhile wait in its socket)
    pacer.tick(PACE_S + 0.8, t0, stalled_s=0.8 - PACE_S)
    assert motor.state == State.ENABLED and motor.lost_comm_at_s == []
    assert clock.now() == pytest.approx(t0 + PACE_S + 0.8)  # the physics caught up all the same
    motor.handle(0x001, bytes.fromhex(HOLD))  # the queued frame is handled: the host was never silent
    assert motor.state == State.ENABLED
    # and a silence after it is judged as before: 0.5 s later, to the tick
    last_rx = motor.last_rx_s
    assert last_rx is not None
    for turn in range(1, int(0.6 / PACE_S) + 1):
        pacer.tick(PACE_S + 0.8 + turn * PACE_S, t0)
    assert motor.state == State.LOST_COMM and motor.lost_comm_at_s == [pytest.approx(last_rx + 0.5)]
    assert pacer.stalls_s == [pytest.approx(0.8 - PACE_S)]


def test_a_gap_between_turns_is_a_stall_only_past_the_threshold() -> None:
    assert STALL_S == 0.1
    assert own_stall_s(0.05) == 0.0 and own_stall_s(STALL_S) == 0.0  # scheduling jitter: the host is judged
    assert own_stall_s(0.8) == pytest.approx(0.8 - PACE_S)
    assert own_stall_s(0.3, period_s=0.01) == pytest.approx(0.29)
