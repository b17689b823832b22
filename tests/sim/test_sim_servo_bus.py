"""Bus behaviour of the simulated servos as on hardware: broadcast PING, id and baud-rate changes, plugging in.

Driven through the unmodified vendor SDKs on the pseudo-terminal (the SDK sets the terminal's speed; the
simulator answers only at each servo's own baud rate).
"""

from __future__ import annotations

import time
from collections.abc import Iterator
from typing import Any

import dynamixel_sdk as dxl
import pytest
import scservo_sdk as scs

from robocal.backends.sim.lerobot_arms import SimArm, seeded_truth
from robocal.backends.sim.servo import BAUD_RATES, SimServo, SimServoBus
from robocal.workflows.lerobot import robot_spec

from .conftest import open_sdk as _open

pytestmark = pytest.mark.timeout(60)


def feetech_broadcast_ping(ph: Any, pk: Any) -> dict[int, int]:
    """LeRobot's Feetech broadcast ping, restated: send PING to 0xFE, read 6-byte status packets until timeout."""
    tx = [0] * 6
    tx[scs.PKT_ID], tx[scs.PKT_LENGTH], tx[scs.PKT_INSTRUCTION] = scs.BROADCAST_ID, 2, scs.INST_PING
    assert pk.txPacket(ph, tx) == scs.COMM_SUCCESS
    ph.setPacketTimeoutMillis(300)
    rx: list[int] = []
    while not ph.isPacketTimeout():
        rx += ph.readPort(64)
    ph.is_using = False
    found: dict[int, int] = {}
    while len(rx) >= 6:
        assert rx[0:2] == [0xFF, 0xFF], rx
        assert (~sum(rx[2:5])) & 0xFF == rx[5]
        found[rx[2]] = rx[4]  # id → error byte
        del rx[:6]
    assert rx == []
    return found


@pytest.fixture
def feetech() -> Iterator[SimServoBus]:
    with SimServoBus([SimServo(i, "sts3215", 1000.0 + i) for i in (3, 1, 2)]) as sim:
        yield sim


@pytest.fixture
def dynamixel() -> Iterator[SimServoBus]:
    with SimServoBus([SimServo(2, "xl430-w250", 100.0), SimServo(5, "xl330-m288", 200.0)]) as sim:
        yield sim


def test_feetech_broadcast_ping_answered_by_every_servo_in_id_order(feetech: SimServoBus) -> None:
    ph, pk = _open(scs, feetech.port, 1_000_000, 0)
    try:
        assert feetech_broadcast_ping(ph, pk) == {1: 0, 2: 0, 3: 0}
        feetech.servos[2].attached = False
        assert feetech_broadcast_ping(ph, pk) == {1: 0, 3: 0}
    finally:
        ph.closePort()


def test_dynamixel_broadcast_ping_reports_model_and_firmware(dynamixel: SimServoBus) -> None:
    ph, pk = _open(dxl, dynamixel.port, 1_000_000, 2.0)
    try:
        found, result = pk.broadcastPing(ph)
        assert result == dxl.COMM_SUCCESS
        assert found == {2: [1060, 52], 5: [1200, 52]}
    finally:
        ph.closePort()


def test_id_change_acknowledged_with_old_id_then_servo_answers_new_id(dynamixel: SimServoBus) -> None:
    ph, pk = _open(dxl, dynamixel.port, 1_000_000, 2.0)
    try:
        result, error = pk.write1ByteTxRx(ph, 5, 7, 9)  # ID register at 7
        assert (result, error) == (dxl.COMM_SUCCESS, 0)
        assert pk.ping(ph, 5)[1] == dxl.COMM_RX_TIMEOUT
        assert pk.ping(ph, 9)[:2] == (1200, dxl.COMM_SUCCESS)
        assert dynamixel.servos[5].bus_id == 9  # the slot keeps its name; the register holds the id
    finally:
        ph.closePort()


@pytest.mark.parametrize(
    ("vendor", "model", "baud_value", "protocol"),
    [("feetech", "sts3215", 4, 0), ("dynamixel", "xl330-m288", 1, 2.0)],
)
def test_baud_change_servo_answers_only_at_its_new_speed(
    vendor: str, model: str, baud_value: int, protocol: float
) -> None:
    sdk = scs if vendor == "feetech" else dxl
    with SimServoBus([SimServo(1, model, 500.0)]) as sim:
        addr = sim.servos[1].table["Baud_Rate"][0]
        ph, pk = _open(sdk, sim.port, 1_000_000, protocol)
        try:
            assert pk.write1ByteTxRx(ph, 1, addr, baud_value) == (sdk.COMM_SUCCESS, 0)  # ack at the old speed
            assert pk.ping(ph, 1)[1] == sdk.COMM_RX_TIMEOUT
            new = BAUD_RATES[vendor][baud_value]  # type: ignore[index]
            assert new in (115_200, 57_600)
            assert ph.setBaudRate(new)
            assert sim.client_baudrate() == new
            assert pk.ping(ph, 1)[1] == sdk.COMM_SUCCESS
        finally:
            ph.closePort()


@pytest.mark.slow
def test_factory_arm_servos_share_id_1_and_are_set_up_one_at_a_time() -> None:
    with SimArm(robot_spec("koch_follower"), factory=True) as arm:
        arm.bus.attach([6])  # only the gripper is plugged in
        ph, pk = _open(dxl, arm.port, 1_000_000, 2.0)
        try:
            assert pk.broadcastPing(ph)[1] == dxl.COMM_RX_TIMEOUT  # Dynamixel X ships at 57600 bit/s
            ph.setBaudRate(57_600)
            found, _ = pk.broadcastPing(ph)
            assert found == {1: [1200, 52]}  # the gripper's xl330-m288, at id 1
            assert pk.write1ByteTxRx(ph, 1, 7, 6) == (dxl.COMM_SUCCESS, 0)
            assert pk.write1ByteTxRx(ph, 6, 8, 3) == (dxl.COMM_SUCCESS, 0)  # 1 Mbit/s
            ph.setBaudRate(1_000_000)
            arm.bus.attach(None)  # every motor plugged in: the others are still at id 1, 57600
            found, _ = pk.broadcastPing(ph)
            assert found == {6: [1200, 52]}
        finally:
            ph.closePort()


def test_last_client_write_is_recorded_per_servo(feetech: SimServoBus) -> None:
    ph, pk = _open(scs, feetech.port, 1_000_000, 0)
    try:
        before = time.monotonic()
        assert pk.write2ByteTxRx(ph, 2, 9, 700) == (scs.COMM_SUCCESS, 0)
        servo = feetech.servos[2]
        assert servo.last_write == "Min_Position_Limit=700"
        assert servo.last_write_time >= before
        assert feetech.servos[1].last_write == ""
    finally:
        ph.closePort()


def test_seeded_truth_is_reproducible_and_differs_from_the_stock_arm() -> None:
    a, b = seeded_truth("so101_follower", 7), seeded_truth("so101_follower", 7)
    assert a == b
    stock = seeded_truth("so101_follower", None)
    assert a != stock
    for name, t in a.items():
        s = stock[name]
        assert abs(t.mid_ticks - s.mid_ticks) <= 150
        assert t.stop_low_ticks < t.mid_ticks < t.stop_high_ticks
