"""Robstride reply addressing with two host ids on one bus (issue 29).

The motor answers a request that carries a host id (types 3, 4, 6, 17, 18, 22) to that host; a type-1 (MIT)
request carries the torque there instead, so its feedback goes to a host the motor keeps: in the simulator the
last host that addressed it (or a fixed ``master_id``). robocal's client takes a reply to its own host id, and
for its MIT requests the asked motor's feedback whatever host it is addressed to.
"""

from __future__ import annotations

import itertools
import struct
from collections.abc import Iterator

import can
import pytest

from robocal.backends.robstride import MotorSpec, RobstrideBus
from robocal.backends.robstride.protocol import CommType, Param, make_id, split_id
from robocal.backends.robstride.sim import SimMotor, SimMotorBus

pytestmark = pytest.mark.timeout(60)

_counter = itertools.count()
REPLY_WAIT_S = 5.0


@pytest.fixture
def line() -> Iterator[tuple[str, SimMotor, can.BusABC]]:
    """A simulated motor (CAN id 7) and a raw listener on its channel that sees every frame."""
    channel = f"rs-hosts-{next(_counter)}"
    motor = SimMotor(can_id=7, model="rs-00", factory_zero_rad=0.25)
    spy = can.Bus(channel=channel, interface="virtual", receive_own_messages=False)
    with SimMotorBus(channel, [motor]):
        try:
            yield channel, motor, spy
        finally:
            spy.shutdown()


def _replies(spy: can.BusABC, count: int) -> list[tuple[int, int, int]]:
    """The next ``count`` frames from the motor as (type, bits 15..8, bits 7..0), requests skipped."""
    out: list[tuple[int, int, int]] = []
    while len(out) < count:
        msg = spy.recv(timeout=REPLY_WAIT_S)
        assert msg is not None, f"only {out}"
        comm, data16, low = split_id(msg.arbitration_id)
        if low != 7:  # not a request to motor 7
            out.append((comm, data16 & 0xFF, low))
    return out


def test_each_request_is_answered_to_its_own_host(line: tuple[str, SimMotor, can.BusABC]) -> None:
    channel, _, spy = line
    with (
        RobstrideBus(channel, [MotorSpec("j", 7)], interface="virtual", host_id=0xFD, timeout_s=REPLY_WAIT_S) as fd,
        RobstrideBus(channel, [MotorSpec("j", 7)], interface="virtual", host_id=0xAA, timeout_s=REPLY_WAIT_S) as aa,
    ):
        assert fd.read_param("j", Param.VBUS) == 24.0
        assert aa.read_param("j", Param.VBUS) == 24.0
        assert fd.read_position("j") == pytest.approx(0.25, abs=1e-6)
        assert aa.enable("j").host_id == 0xAA
        assert fd.stop("j").host_id == 0xFD
    assert _replies(spy, 5) == [
        (CommType.PARAM_READ, 7, 0xFD),
        (CommType.PARAM_READ, 7, 0xAA),
        (CommType.PARAM_READ, 7, 0xFD),
        (CommType.FEEDBACK, 7, 0xAA),
        (CommType.FEEDBACK, 7, 0xFD),
    ]


def test_mit_feedback_after_another_host_talked_to_the_motor(line: tuple[str, SimMotor, can.BusABC]) -> None:
    """The issue's defect: host 0xAA enables the motor, then robocal (0xFD) polls it with MIT zero-torque."""
    channel, motor, spy = line
    other = can.Bus(channel=channel, interface="virtual", receive_own_messages=False)
    try:
        other.send(can.Message(arbitration_id=make_id(CommType.ENABLE, 0xAA, 7), data=bytes(8)))
        assert _replies(spy, 1) == [(CommType.FEEDBACK, 7, 0xAA)]
        with RobstrideBus(channel, [MotorSpec("j", 7)], interface="virtual", timeout_s=REPLY_WAIT_S) as bus:
            fb = bus.zero_torque()["j"]
            # the feedback went to 0xAA, the last host that addressed the motor, and robocal took it
            assert (fb.motor_id, fb.host_id, fb.mode) == (7, 0xAA, 2)
            assert fb.position_rad == pytest.approx(0.25, abs=1e-3)
            assert motor.last_command == pytest.approx((0.0, 0.0, 0.0, 0.0, 0.0), abs=1e-3)  # 16-bit MIT fields
            # a request that carries the host id is still answered to robocal's 0xFD
            assert bus.read_param("j", Param.VBUS) == 24.0
            assert bus.zero_torque()["j"].host_id == 0xFD
    finally:
        other.shutdown()
    assert _replies(spy, 3) == [
        (CommType.FEEDBACK, 7, 0xAA),
        (CommType.PARAM_READ, 7, 0xFD),
        (CommType.FEEDBACK, 7, 0xFD),
    ]


def test_a_fixed_master_id_answers_every_mit_command_there(line: tuple[str, SimMotor, can.BusABC]) -> None:
    channel, motor, spy = line
    motor.master_id = 0x01
    with RobstrideBus(channel, [MotorSpec("j", 7)], interface="virtual", timeout_s=REPLY_WAIT_S) as bus:
        assert bus.zero_torque()["j"].host_id == 0x01
        assert bus.enable("j").host_id == 0xFD  # a request with a host id is still answered to it
        assert bus.mit_command("j", 0.0, 0.0, 0.0, 0.0, 0.0).host_id == 0x01
    assert _replies(spy, 3) == [(CommType.FEEDBACK, 7, 0x01), (CommType.FEEDBACK, 7, 0xFD), (CommType.FEEDBACK, 7, 0x01)]


def test_param_reply_to_another_host_is_not_taken(line: tuple[str, SimMotor, can.BusABC]) -> None:
    """robocal's read waits for the reply to its own host id; one addressed to 0xAA does not answer it."""
    channel, _, _ = line
    other = can.Bus(channel=channel, interface="virtual", receive_own_messages=False)
    try:
        with RobstrideBus(channel, [MotorSpec("j", 7)], interface="virtual", timeout_s=REPLY_WAIT_S) as bus:
            # 0xAA reads vbus first; its reply (24.0, to 0xAA) reaches robocal's bus before robocal's own request
            other.send(
                can.Message(
                    arbitration_id=make_id(CommType.PARAM_READ, 0xAA, 7),
                    data=struct.pack("<HHI", Param.VBUS, 0, 0),
                )
            )
            assert other.recv(timeout=REPLY_WAIT_S) is not None
            assert bus.read_param("j", Param.CAN_TIMEOUT) == 0.0  # not the 24.0 addressed to 0xAA
    finally:
        other.shutdown()
