"""The simulated STS3215 behaves as Feetech's memory table says (issue 29), driven through the unmodified SDK.

Factory values, "set middle" (Torque_Enable = 128), Torque_Limit 0 and Response_Status_Level 0, asserted on the
values the SDK reads, the bytes on the wire and the simulator's state. The factory values below are restated from
Feetech's ST3215 memory table (see docs/sim.md), not imported from the simulator.
"""

from __future__ import annotations

import math
from collections.abc import Iterator
from typing import Any

import pytest
import scservo_sdk as scs

from robocal.backends.feetech import FeetechBus
from robocal.backends.sim.physics import JointPlant, PlantParams, SimClock
from robocal.backends.sim.servo import SimServo, SimServoBus

from .conftest import open_sdk

pytestmark = pytest.mark.timeout(60)

FACTORY = {  # address: (bytes, value) of a new STS3215 (Feetech's table; voltage and temperature assumed)
    0: (1, 3),
    5: (1, 1),
    6: (1, 0),
    7: (1, 0),
    8: (1, 1),
    9: (2, 0),
    11: (2, 4095),
    13: (1, 70),
    14: (1, 80),
    15: (1, 40),
    16: (2, 1000),
    18: (1, 12),
    19: (1, 44),
    20: (1, 47),
    21: (1, 32),
    22: (1, 32),
    23: (1, 0),
    24: (2, 16),
    26: (1, 1),
    27: (1, 1),
    28: (2, 500),
    30: (1, 1),
    31: (2, 0),
    33: (1, 0),
    34: (1, 20),
    35: (1, 200),
    36: (1, 80),
    37: (1, 10),
    38: (1, 200),
    39: (1, 10),
    40: (1, 0),
    48: (2, 1000),
    62: (1, 74),
    63: (1, 25),
}


@pytest.fixture
def sdk() -> Iterator[tuple[SimServoBus, Any, Any]]:
    with SimServoBus([SimServo(1, "sts3215", 1000.0), SimServo(2, "sts3215", 4096 + 3500.0)]) as sim:
        ph, pk = open_sdk(scs, sim.port, 1_000_000, 0)
        try:
            yield sim, ph, pk
        finally:
            ph.closePort()


def _read(ph: Any, pk: Any, motor_id: int, addr: int, size: int) -> int:
    value, result, error = (pk.read1ByteTxRx if size == 1 else pk.read2ByteTxRx)(ph, motor_id, addr)
    assert (result, error) == (scs.COMM_SUCCESS, 0), (addr, result, error)
    return int(value)


def test_a_new_sts3215_reads_feetechs_factory_values(sdk: tuple[SimServoBus, Any, Any]) -> None:
    _sim, ph, pk = sdk
    got = {addr: _read(ph, pk, 1, addr, size) for addr, (size, _) in FACTORY.items()}
    assert got == {addr: value for addr, (_, value) in FACTORY.items()}
    assert _read(ph, pk, 1, 3, 2) == 777  # Model_Number
    data, result, _ = pk.readTxRx(ph, 1, 48, 2)  # Torque_Limit 1000, little-endian on the wire
    assert (result, list(data)) == (scs.COMM_SUCCESS, [0xE8, 0x03])


@pytest.mark.parametrize(("motor_id", "actual", "offset_raw"), [(1, 1000, 0x800 | 1048), (2, 4096 + 3500, 1452)])
def test_set_middle_makes_the_present_position_read_2048(
    sdk: tuple[SimServoBus, Any, Any], motor_id: int, actual: int, offset_raw: int
) -> None:
    sim, ph, pk = sdk
    sim.packet_log = []
    assert pk.write1ByteTxRx(ph, motor_id, 40, 128) == (scs.COMM_SUCCESS, 0)
    if motor_id == 1:  # Feetech's CalibrationOfs(1) and its acknowledgement, byte for byte
        assert sim.packet_log == [
            ("rx", bytes.fromhex("FF FF 01 04 03 28 80 4F")),
            ("tx", bytes.fromhex("FF FF 01 02 00 FC")),
        ]
    assert _read(ph, pk, motor_id, 56, 2) == 2048  # Present_Position
    assert _read(ph, pk, motor_id, 31, 2) == offset_raw  # Homing_Offset, sign-magnitude (bit 11)
    assert _read(ph, pk, motor_id, 40, 1) == 0  # 128 does not switch the torque on
    servo = sim.servos[motor_id]
    assert servo.actual_ticks == actual  # the shaft did not move
    assert servo.get_reg("Torque_Enable") == 0
    assert pk.write2ByteTxRx(ph, motor_id, 42, 2048) == (scs.COMM_SUCCESS, 0)  # torque off: a goal does not move it
    assert servo.actual_ticks == actual


def test_torque_limit_0_gives_no_torque(sdk: tuple[SimServoBus, Any, Any]) -> None:
    sim, ph, pk = sdk
    assert pk.write2ByteTxRx(ph, 1, 48, 0) == (scs.COMM_SUCCESS, 0)  # Torque_Limit 0
    assert pk.write1ByteTxRx(ph, 1, 40, 1) == (scs.COMM_SUCCESS, 0)
    assert pk.write2ByteTxRx(ph, 1, 42, 3000) == (scs.COMM_SUCCESS, 0)  # Goal_Position
    assert sim.servos[1].actual_ticks == 1000
    assert _read(ph, pk, 1, 56, 2) == 1000
    assert _read(ph, pk, 1, 42, 2) == 3000  # the goal is stored, only not driven to
    assert pk.write2ByteTxRx(ph, 1, 48, 1000) == (scs.COMM_SUCCESS, 0)
    assert pk.write2ByteTxRx(ph, 1, 42, 3000) == (scs.COMM_SUCCESS, 0)
    assert sim.servos[1].actual_ticks == 3000


def test_torque_limit_0_gives_no_torque_with_physics() -> None:
    clock, tick = SimClock(), 2 * math.pi / 4096
    servo = SimServo(1, "sts3215", 2048.0)
    plant = JointPlant(PlantParams(stop_lower_rad=-1.0, stop_upper_rad=1.0), q0_rad=0.0)
    servo.firmware = servo.kind.firmware(servo, plant, clock, zero_ticks=2048.0)
    with SimServoBus([servo], clock=clock) as sim, FeetechBus(sim.port, {1: "sts3215"}, packet_timeout_ms=500.0) as bus:
        bus.write("Torque_Limit", 1, 0)
        bus.write("Torque_Enable", 1, 1)
        bus.write("Goal_Position", 1, 2048 + round(0.5 / tick))
        for _ in range(50):
            clock.sleep(0.02)
            bus.read("Present_Position", 1)
        assert abs(plant.q_rad) < 1e-9
        assert bus.read("Present_Position", 1) == 2048
        bus.write("Torque_Limit", 1, 1000)
        for _ in range(50):
            clock.sleep(0.02)
            bus.read("Present_Position", 1)
        assert plant.q_rad == pytest.approx(0.5, abs=0.02)


def test_response_status_level_0_answers_ping_and_read_only(sdk: tuple[SimServoBus, Any, Any]) -> None:
    sim, ph, pk = sdk
    assert pk.write1ByteTxRx(ph, 1, 8, 0) == (scs.COMM_SUCCESS, 0)  # acknowledged at the level it arrived at
    sim.packet_log = []
    assert pk.write2ByteTxRx(ph, 1, 42, 1234) == (scs.COMM_RX_TIMEOUT, 0)  # applied, not answered
    assert sim.servos[1].get_reg("Goal_Position") == 1234
    assert [kind for kind, _ in sim.packet_log] == ["rx"]
    assert pk.ping(ph, 1) == (777, scs.COMM_SUCCESS, 0)  # the SDK's ping: PING, then READ of Model_Number
    assert _read(ph, pk, 1, 42, 2) == 1234
    assert pk.action(ph, 1) == scs.COMM_RX_TIMEOUT  # an instruction it does not model, unanswered too
    assert [kind for kind, _ in sim.packet_log] == ["rx", "rx", "tx", "rx", "tx", "rx", "tx", "rx"]
    assert pk.write1ByteTxRx(ph, 2, 8, 0) == (scs.COMM_SUCCESS, 0)
    assert pk.write1ByteTxOnly(ph, 1, 8, 1) == scs.COMM_SUCCESS  # back to level 1: writes answered again
    assert pk.write2ByteTxRx(ph, 1, 42, 2048) == (scs.COMM_SUCCESS, 0)
    assert _read(ph, pk, 2, 8, 1) == 0
