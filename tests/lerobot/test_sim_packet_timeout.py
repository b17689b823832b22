"""A simulated arm in this process on a pseudo-terminal is waited for at least 1 s per status packet.

Its reply waits for the simulator's thread, which a starved test process may not run for hundreds of ms: with
the 100 ms of a real port, tests on a loaded machine failed "There is no status packet". A real port and an
in-process port (``inproc://``, answered within the call, on the simulated clock) keep 100 ms.
"""

from __future__ import annotations

import os
import pty
import threading

import pytest

from robocal.workflows.lerobot import open_arm, open_bus, robot_spec
from robocal.workflows.lerobot.arms import SIM_PACKET_TIMEOUT_MS, open_sim_bus

pytest.importorskip("scservo_sdk")
pytest.importorskip("dynamixel_sdk")


def _timeout_ms(bus: object) -> float:
    handler = bus._port_handler  # type: ignore[attr-defined]
    handler.setPacketTimeout(10)  # what the SDK calls before each read: the floor is applied over its own
    return float(handler.packet_timeout)


@pytest.mark.parametrize("robot", ["so101_follower", "koch_follower"])
def test_the_sim_port_waits_a_second(robot: str, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.delenv("ROBOCAL_REPLY_TIMEOUT_MS", raising=False)
    with open_arm(robot_spec(robot), "sim") as (bus, _arm):
        assert SIM_PACKET_TIMEOUT_MS == 1000.0
        assert _timeout_ms(bus) >= 1000.0


def test_a_starved_simulator_thread_is_still_answered(monkeypatch: pytest.MonkeyPatch) -> None:
    """The simulator's thread held off for 0.3 s (its lock taken): the read waits for it instead of failing."""
    monkeypatch.delenv("ROBOCAL_REPLY_TIMEOUT_MS", raising=False)
    spec = robot_spec("so101_follower")
    with open_arm(spec, "sim") as (bus, arm):
        held, release = threading.Event(), threading.Event()

        def hold() -> None:
            with arm.bus.lock:
                held.set()
                release.wait(60)

        holder = threading.Thread(target=hold, daemon=True)
        holder.start()
        assert held.wait(60)
        timer = threading.Timer(0.3, release.set)
        timer.start()
        try:
            assert bus.read("ID", 1) == 1
        finally:
            release.set()
            timer.cancel()
            holder.join(60)


def test_a_real_port_and_an_inproc_port_keep_100_ms(monkeypatch: pytest.MonkeyPatch) -> None:
    from robocal.backends.sim.lerobot_arms import SimArm

    monkeypatch.delenv("ROBOCAL_REPLY_TIMEOUT_MS", raising=False)
    spec = robot_spec("so101_follower")
    with SimArm(spec, transport="inproc") as arm:
        bus = open_sim_bus(spec, arm)
        try:
            assert _timeout_ms(bus) == pytest.approx(100.0)
        finally:
            bus.close()
    master, slave = pty.openpty()  # a port nothing answers on: what open_bus gives any serial device
    try:
        bus = open_bus(spec, os.ttyname(slave))
        try:
            assert _timeout_ms(bus) == pytest.approx(100.0)
        finally:
            bus.close()
    finally:
        os.close(master)
        os.close(slave)
