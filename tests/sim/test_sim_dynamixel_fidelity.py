"""The simulated Dynamixel X servos as the e-Manual and DynamixelSDK say (issue 29), through the unmodified SDK.

Factory values per model (restated from the e-Manual pages, see docs/sim.md), Status_Return_Level, Bulk Read,
Fast Sync Read and Fast Bulk Read (DynamixelSDK's GroupBulkRead / GroupSyncRead), asserted on values and bytes.
"""

from __future__ import annotations

from collections.abc import Iterator
from typing import Any

import dynamixel_sdk as dxl
import pytest

from robocal.backends.sim.servo import SimServo, SimServoBus

from .conftest import open_sdk

pytestmark = pytest.mark.timeout(60)

XL330_M288 = {  # address: (bytes, value)
    9: (1, 250), 10: (1, 0), 11: (1, 3), 12: (1, 255), 13: (1, 2), 20: (4, 0), 24: (4, 10), 31: (1, 70),
    32: (2, 70), 34: (2, 35), 36: (2, 885), 38: (2, 1750), 44: (4, 445), 48: (4, 4095), 52: (4, 0), 60: (1, 0),
    62: (1, 140), 63: (1, 53), 64: (1, 0), 68: (1, 2), 76: (2, 1600), 78: (2, 180), 80: (2, 0), 82: (2, 0),
    84: (2, 400),
}  # fmt: skip
XL430_W250 = {
    31: (1, 72), 32: (2, 140), 34: (2, 60), 36: (2, 885), 44: (4, 265), 63: (1, 52), 68: (1, 2), 76: (2, 1000),
    78: (2, 100), 80: (2, 4000), 82: (2, 0), 84: (2, 640),
}  # fmt: skip


@pytest.fixture
def sdk() -> Iterator[tuple[SimServoBus, Any, Any]]:
    with SimServoBus([SimServo(1, "xl330-m288", 166.0), SimServo(2, "xl430-w250", 4096 + 2079.0)]) as sim:
        ph, pk = open_sdk(dxl, sim.port, 1_000_000, 2.0)
        try:
            yield sim, ph, pk
        finally:
            ph.closePort()


def _read(ph: Any, pk: Any, motor_id: int, addr: int, size: int) -> int:
    fn = {1: pk.read1ByteTxRx, 2: pk.read2ByteTxRx, 4: pk.read4ByteTxRx}[size]
    value, result, error = fn(ph, motor_id, addr)
    assert (result, error) == (dxl.COMM_SUCCESS, 0), (addr, result, error)
    return int(value)


def test_new_x_series_servos_read_their_factory_values(sdk: tuple[SimServoBus, Any, Any]) -> None:
    _sim, ph, pk = sdk
    for motor_id, table in ((1, XL330_M288), (2, XL430_W250)):
        got = {addr: _read(ph, pk, motor_id, addr, size) for addr, (size, _) in table.items()}
        assert got == {addr: value for addr, (_, value) in table.items()}, motor_id


def test_status_return_level_gates_replies(sdk: tuple[SimServoBus, Any, Any]) -> None:
    sim, ph, pk = sdk
    assert pk.write1ByteTxRx(ph, 1, 68, 1) == (dxl.COMM_SUCCESS, 0)  # acknowledged at the level it arrived at
    assert pk.write4ByteTxRx(ph, 1, 116, 1234) == (dxl.COMM_RX_TIMEOUT, 0)  # applied, not answered
    assert sim.servos[1].get_reg("Goal_Position") == 1234
    assert _read(ph, pk, 1, 116, 4) == 1234
    assert pk.ping(ph, 1) == (1200, dxl.COMM_SUCCESS, 0)
    assert pk.write1ByteTxOnly(ph, 1, 68, 0) == dxl.COMM_SUCCESS
    assert pk.read4ByteTxRx(ph, 1, 116)[1] == dxl.COMM_RX_TIMEOUT  # level 0: PING only
    assert pk.ping(ph, 1) == (1200, dxl.COMM_SUCCESS, 0)
    assert sim.servos[1].get_reg("Status_Return_Level") == 0
    group = dxl.GroupSyncRead(ph, pk, 132, 4)  # group reads are answered whatever the level
    assert group.addParam(1)
    assert group.fastSyncRead() == dxl.COMM_SUCCESS
    assert group.getData(1, 132, 4) == 166


def test_bulk_read_answers_one_status_per_servo(sdk: tuple[SimServoBus, Any, Any]) -> None:
    sim, ph, pk = sdk
    group = dxl.GroupBulkRead(ph, pk)
    assert group.addParam(1, 132, 4) and group.addParam(2, 63, 1)
    sim.packet_log = []
    assert group.txRxPacket() == dxl.COMM_SUCCESS
    assert (group.getData(1, 132, 4), group.getData(2, 63, 1)) == (166, 52)
    assert [kind for kind, _ in sim.packet_log] == ["rx", "tx", "tx"]
    assert sim.packet_log[1][1][4] == 1 and sim.packet_log[2][1][4] == 2


def test_fast_sync_read_answers_one_combined_packet(sdk: tuple[SimServoBus, Any, Any]) -> None:
    sim, ph, pk = sdk
    group = dxl.GroupSyncRead(ph, pk, 132, 4)
    assert group.addParam(1) and group.addParam(2)
    sim.packet_log = []
    assert group.fastSyncRead() == dxl.COMM_SUCCESS
    assert (group.getData(1, 132, 4), group.getData(2, 132, 4)) == (166, 2079)
    assert sim.packet_log == [  # the reference's worked example, byte for byte
        ("rx", bytes.fromhex("FF FF FD 00 FE 09 00 8A 84 00 04 00 01 02 4D 72")),
        ("tx", bytes.fromhex("FF FF FD 00 FE 11 00 55 00 01 A6 00 00 00 74 3B 00 02 1F 08 00 00 1C 36")),
    ]


def test_fast_bulk_read_answers_one_combined_packet(sdk: tuple[SimServoBus, Any, Any]) -> None:
    sim, ph, pk = sdk
    group = dxl.GroupBulkRead(ph, pk)
    assert group.addParam(1, 132, 4) and group.addParam(2, 36, 2)
    sim.packet_log = []
    assert group.fastBulkRead() == dxl.COMM_SUCCESS
    assert (group.getData(1, 132, 4), group.getData(2, 36, 2)) == (166, 885)
    assert [kind for kind, _ in sim.packet_log] == ["rx", "tx"]
    reply = sim.packet_log[1][1]
    assert reply[:8] == bytes([0xFF, 0xFF, 0xFD, 0x00, 0xFE, 15, 0, 0x55])  # 1 + (4 + 4) + (2 + 4)
    assert reply[8:14] == bytes([0, 1, 0xA6, 0, 0, 0]) and reply[16:20] == bytes([0, 2, 0x75, 0x03])


def test_bulk_write_is_applied_by_each_servo_and_answered_by_none(sdk: tuple[SimServoBus, Any, Any]) -> None:
    sim, ph, pk = sdk
    group = dxl.GroupBulkWrite(ph, pk)
    assert group.addParam(1, 32, 2, [0xA0, 0x00]) and group.addParam(2, 31, 1, [0x50])
    sim.packet_log = []
    assert group.txPacket() == dxl.COMM_SUCCESS
    assert _read(ph, pk, 1, 32, 2) == 160 and _read(ph, pk, 2, 31, 1) == 80  # Max_Voltage_Limit, Temperature_Limit
    assert sim.packet_log[0] == (  # the e-Manual's Bulk Write example, byte for byte
        "rx",
        bytes.fromhex("FF FF FD 00 FE 10 00 93 01 20 00 02 00 A0 00 02 1F 00 01 00 50 B7 68"),
    )
    assert [kind for kind, _ in sim.packet_log] == ["rx", "rx", "tx", "rx", "tx"]  # no status for the bulk write


def test_a_value_outside_a_registers_range_is_refused_with_a_data_range_error(
    sdk: tuple[SimServoBus, Any, Any],
) -> None:
    """e-Manual ranges: Min/Max_Position_Limit 0-4095, Homing_Offset ±1 044 479; a write outside is answered with
    the Data Range error (4) and not applied (before, any value the 4 bytes hold was taken: a LeRobot file with
    range_max 70000 was written to a simulated Koch without complaint)."""
    sim, ph, pk = sdk
    assert pk.write4ByteTxRx(ph, 1, 48, 70000) == (dxl.COMM_SUCCESS, 4)
    assert pk.write4ByteTxRx(ph, 1, 52, 0xFFFFFFFD) == (dxl.COMM_SUCCESS, 4)  # -3
    assert pk.write4ByteTxRx(ph, 2, 20, 1_044_480) == (dxl.COMM_SUCCESS, 4)
    assert (_read(ph, pk, 1, 48, 4), _read(ph, pk, 1, 52, 4), _read(ph, pk, 2, 20, 4)) == (4095, 0, 0)
    assert pk.write4ByteTxRx(ph, 1, 48, 4000) == (dxl.COMM_SUCCESS, 0)
    assert pk.write4ByteTxRx(ph, 2, 20, (1 << 32) - 1_044_479) == (dxl.COMM_SUCCESS, 0)  # the lowest it takes
    assert (sim.servos[1].get_reg("Max_Position_Limit"), sim.servos[2].get_reg("Homing_Offset")) == (4000, -1_044_479)
