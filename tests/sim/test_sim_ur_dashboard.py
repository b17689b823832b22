"""The simulated UR controller reports a running arm (RobotModeData) and serves the dashboard (29999 protocol).

RobotModeData is checked against a golden 47-byte vector and read with python-urx's own layout string (the
3.5+ form it picks by size 47); the dashboard is driven over a real loopback TCP socket by a plain socket
client, with the reply texts URCL's dashboard client matches.
"""

from __future__ import annotations

import socket
import struct
from collections.abc import Iterator

import pytest

from robocal.backends.sim.ur_arm_state import (
    RobotModeSample,
    UrArmState,
    encode_robot_mode_data,
    parse_robot_mode_data,
)
from robocal.backends.sim.ur_controller import SimUrController, build_robot_state
from robocal.backends.sim.ur_dashboard import SimUrDashboard
from robocal.backends.ur_primary import PrimaryClient, iter_subpackages
from robocal.core.ur import nominal_dh

pytestmark = pytest.mark.timeout(60)

GOLDEN_RUNNING = bytes.fromhex(
    "0000002F00" "00000000075BCD15" "01010100000000" "07" "00"
    "3FF0000000000000" "3FF0000000000000" "3FF0000000000000" "00"
)
"""RobotModeData of a powered, enabled, running arm (mode 7), no stop, speed fractions 1.0, timestamp
123456789 — the worked example computed from the 5.x layout."""

URX_35 = "!IBQ???????BBdddB"
"""python-urx's RobotModeData layout for a 47-byte sub-package (its '3.5' branch)."""

HANG_GUARD_S = 10.0


def test_running_arm_encodes_to_the_golden_vector() -> None:
    assert encode_robot_mode_data(RobotModeSample(timestamp=123456789)) == GOLDEN_RUNNING
    assert len(GOLDEN_RUNNING) == 47


def test_urx_layout_reads_a_running_arm() -> None:
    (size, sub_type, ts, connected, enabled, power, estop, pstop, prog, paused, mode, ctrl, frac, scaling,
     limit, _reserved) = struct.unpack(URX_35, GOLDEN_RUNNING)  # fmt: skip
    assert (size, sub_type, ts) == (47, 0, 123456789)
    # python-urx's secmon.running: mode 7, enabled, no e-stop, no protective stop, connected, powered
    assert mode == 7 and enabled and not estop and not pstop and connected and power
    assert (prog, paused, ctrl) == (False, False, 0)
    assert (frac, scaling, limit) == (1.0, 1.0, 1.0)


def test_parse_round_trip_and_refusals() -> None:
    s = RobotModeSample(timestamp=5, robot_mode=3, robot_power_on=False, program_paused=True)
    assert parse_robot_mode_data(encode_robot_mode_data(s)) == s
    with pytest.raises(Exception, match="expected sub-type 0 of 47 bytes, got type 0 of 46 bytes"):
        parse_robot_mode_data(GOLDEN_RUNNING[:46])


def test_robot_state_starts_with_the_running_robot_mode_data() -> None:
    state = build_robot_state(nominal_dh("ur5e"))
    first_type, first = next(iter_subpackages(state[5:]))
    assert first_type == 0
    assert first == encode_robot_mode_data(RobotModeSample())
    assert len(state) == 1386  # the URSim layout keeps its size


def _robot_modes(client: PrimaryClient) -> Iterator[RobotModeSample]:
    while True:
        msg_type, payload = client.read_message()
        if msg_type == 16:
            for sub_type, sub in iter_subpackages(payload):
                if sub_type == 0:
                    yield parse_robot_mode_data(sub)


def _wait_mode(client: PrimaryClient, robot_mode: int) -> RobotModeSample:
    """The first RobotModeData with ``robot_mode`` (bounded by the client's deadline)."""
    for sample in _robot_modes(client):
        if sample.robot_mode == robot_mode:
            return sample
    raise AssertionError("unreachable")


class _Line:
    """A plain line-based socket client."""

    def __init__(self, address: tuple[str, int]) -> None:
        self.sock = socket.create_connection(address, timeout=HANG_GUARD_S)
        self.buf = b""

    def read_line(self) -> str:
        while b"\n" not in self.buf:
            data = self.sock.recv(4096)
            if not data:
                raise ConnectionError(f"closed; pending {self.buf!r}")
            self.buf += data
        line, self.buf = self.buf.split(b"\n", 1)
        return line.decode()

    def ask(self, command: str) -> str:
        self.sock.sendall(command.encode() + b"\n")
        return self.read_line()


@pytest.fixture
def controller() -> Iterator[tuple[UrArmState, SimUrController, SimUrDashboard]]:
    arm = UrArmState(model="UR5")
    with (
        SimUrController(nominal_dh("ur5e"), arm=arm, moving=False) as primary,
        SimUrDashboard(arm) as dashboard,
    ):
        yield arm, primary, dashboard


def test_primary_client_reads_a_running_arm_that_follows_the_arm_state(controller) -> None:
    arm, primary, _ = controller
    with PrimaryClient(*primary.address, timeout_s=HANG_GUARD_S) as client:
        first = next(_robot_modes(client))
        assert first.robot_mode == 7 and first.robot_power_on and first.real_robot_enabled
        assert not first.emergency_stopped and not first.protective_stopped
        arm.power_off()
        off = _wait_mode(client, 3)
        assert not off.robot_power_on and off.timestamp > first.timestamp


def test_dashboard_greeting_and_queries(controller) -> None:
    _, _, dashboard = controller
    c = _Line(dashboard.address)
    assert c.read_line() == "Connected: Universal Robots Dashboard Server"
    assert c.ask("robotmode") == "Robotmode: RUNNING"
    assert c.ask("safetymode") == "Safetymode: NORMAL"
    assert c.ask("safetystatus") == "Safetystatus: NORMAL"
    assert c.ask("programState") == "STOPPED <unnamed>"
    assert c.ask("running") == "Program running: false"
    assert c.ask("get robot model") == "UR5"
    assert c.ask("get serial number").startswith("20")
    assert c.ask("PolyscopeVersion").startswith("URSoftware 5.8.0.0")
    assert c.ask("version") == "5.8.0.0"
    assert c.ask("is in remote control") == "true"
    assert c.ask("fly to the moon") == "Could not understand: 'fly to the moon'"
    assert c.ask("quit") == "Disconnected"
    assert c.sock.recv(10) == b""  # the server hung up
    c.sock.close()


def test_dashboard_power_cycle_is_seen_on_the_primary_stream(controller) -> None:
    _, primary, dashboard = controller
    c = _Line(dashboard.address)
    c.read_line()
    with PrimaryClient(*primary.address, timeout_s=HANG_GUARD_S) as client:
        assert c.ask("power off") == "Powering off"
        assert c.ask("robotmode") == "Robotmode: POWER_OFF"
        assert _wait_mode(client, 3).robot_power_on is False
        assert c.ask("brake release") == "Brake releasing"
        assert c.ask("robotmode") == "Robotmode: POWER_OFF"  # brakes stay on while unpowered
        assert c.ask("power on") == "Powering on"
        assert c.ask("robotmode") == "Robotmode: IDLE"
        idle = _wait_mode(client, 5)
        assert idle.robot_power_on and idle.real_robot_enabled
        assert c.ask("brake release") == "Brake releasing"
        assert c.ask("robotmode") == "Robotmode: RUNNING"
        assert _wait_mode(client, 7).robot_power_on
    c.sock.close()


def test_dashboard_program_commands(controller) -> None:
    arm, primary, dashboard = controller
    c = _Line(dashboard.address)
    c.read_line()
    assert c.ask("play") == "Failed to execute: play"  # nothing loaded
    assert c.ask("load /programs/pick.urp") == "Loading program: /programs/pick.urp"
    assert c.ask("programState") == "STOPPED /programs/pick.urp"
    assert c.ask("play") == "Starting program"
    assert c.ask("programState") == "PLAYING /programs/pick.urp"
    assert c.ask("running") == "Program running: true"
    with PrimaryClient(*primary.address, timeout_s=HANG_GUARD_S) as client:
        assert next(_robot_modes(client)).program_running is True
    assert c.ask("pause") == "Pausing program"
    assert c.ask("programState") == "PAUSED /programs/pick.urp"
    assert c.ask("stop") == "Stopped"
    assert c.ask("programState") == "STOPPED /programs/pick.urp"
    assert c.ask("pause") == "Failed to execute: pause"
    assert c.ask("unlock protective stop") == "Protective stop releasing"
    assert c.ask("close safety popup") == "closing safety popup"
    assert c.ask("restart safety") == "Restarting safety"
    assert arm.robot_mode_name == "POWER_OFF"
    c.sock.close()


def test_dashboard_serves_clients_side_by_side_and_stops_cleanly() -> None:
    arm = UrArmState()
    dashboard = SimUrDashboard(arm).start()
    try:
        a, b = _Line(dashboard.address), _Line(dashboard.address)
        assert a.read_line() == b.read_line() == "Connected: Universal Robots Dashboard Server"
        # two commands in one segment, and one split over two: one reply line each
        a.sock.sendall(b"robotmode\nrunning\n")
        assert (a.read_line(), a.read_line()) == ("Robotmode: RUNNING", "Program running: false")
        b.sock.sendall(b"power o")
        b.sock.sendall(b"ff\n")
        assert b.read_line() == "Powering off"
        assert a.ask("robotmode") == "Robotmode: POWER_OFF"  # one arm behind every connection
    finally:
        dashboard.stop()
    assert a.sock.recv(10) == b"" and b.sock.recv(10) == b""
    a.sock.close()
    b.sock.close()
