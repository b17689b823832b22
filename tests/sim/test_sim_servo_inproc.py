"""The in-process port of the simulated servo buses: the unmodified SDKs, the same packets, no pty, no thread.

``SimServoBus(..., transport="inproc")`` registers an ``inproc://`` port; robocal's FeetechBus / DynamixelBus open
it where the SDK would open ``serial.Serial``; every byte still goes through the SDK's PortHandler and
PacketHandler and through the simulator's packet parser.
"""

from __future__ import annotations

import threading

import pytest
import scservo_sdk as scs

from robocal.backends import inproc_serial
from robocal.backends.dynamixel import DynamixelBus
from robocal.backends.feetech import FeetechBus
from robocal.backends.sim.servo import SimServo, SimServoBus
from robocal.backends.sim.servo_inproc import InProcessSerial
from robocal.errors import CalibTimeoutError, DeviceError, UsageError

pytestmark = pytest.mark.timeout(120)

MODELS = [("sts3215", FeetechBus), ("xl330-m288", DynamixelBus)]
PING = {"sts3215": b"\xff\xff\x01\x02\x01\xfb", "xl330-m288": b"\xff\xff\xfd\x00\x01\x03\x00\x01\x19\x4e"}
"""The PING instruction to id 1 the SDKs send (Feetech protocol 0; Dynamixel protocol 2.0 with its CRC)."""


def _session(
    model: str, cls: type[FeetechBus] | type[DynamixelBus], transport: str
) -> list[tuple[str, bytes]]:
    """A few register operations of every kind; the packet log of the simulator."""
    servos = [SimServo(1, model, 1000.0), SimServo(2, model, 3000.0)]
    with SimServoBus(servos, transport=transport) as sim:
        sim.packet_log = []
        with cls(sim.port, {1: model, 2: model}, packet_timeout_ms=2000.0) as bus:
            assert bus.ping(1) == servos[0].get_reg("Model_Number")
            assert bus.read("Present_Position", 1) == 1000
            bus.write("Torque_Enable", 2, 1)
            bus.sync_write("Goal_Position", {1: 1200, 2: 2900})
            assert bus.sync_read("Present_Position", [1, 2]) == {1: 1000, 2: 2900}  # torque off: 1 stays
            assert bus.sync_read_block(["Present_Position", "ID"], [2]) == {
                2: {"Present_Position": 2900, "ID": 2}
            }
        return sim.packet_log


@pytest.mark.parametrize(("model", "cls"), MODELS, ids=["feetech", "dynamixel"])
def test_the_same_packets_byte_for_byte_as_on_the_pty(
    model: str, cls: type[FeetechBus] | type[DynamixelBus]
) -> None:
    pty, inproc = _session(model, cls, "pty"), _session(model, cls, "inproc")
    assert inproc == pty
    # ping (scservo_sdk also reads the model number), read, write: each answered; SYNC_WRITE: no status;
    # SYNC_READ of two: two status packets; the block read: one
    ping = ["rx", "tx", "rx", "tx"] if model == "sts3215" else ["rx", "tx"]
    assert [d for d, _ in inproc] == [*ping, "rx", "tx", "rx", "tx", "rx", "rx", "tx", "tx", "rx", "tx"]
    assert inproc[0] == ("rx", PING[model])


@pytest.mark.parametrize(("model", "cls"), MODELS, ids=["feetech", "dynamixel"])
def test_a_servo_that_does_not_answer_times_out_on_the_ports_own_time(
    model: str, cls: type[FeetechBus] | type[DynamixelBus]
) -> None:
    with (
        SimServoBus([SimServo(1, model, 1000.0)], transport="inproc") as sim,
        cls(sim.port, {1: model, 2: model}, retries=3, packet_timeout_ms=100.0) as bus,
    ):
        with pytest.raises(CalibTimeoutError, match="motor 2: read 'Present_Position' failed after 4 tries"):
            bus.read("Present_Position", 2)
        client = sim._client
        assert isinstance(client, InProcessSerial)
        # a 100 ms timeout is 101 empty reads of 1 ms of the port's time, for each of the 4 tries
        assert client.empty_reads == 4 * 101 and client.now_ms() == pytest.approx(404.0)
        sim.silent_ids.add(1)
        with pytest.raises(CalibTimeoutError, match="sync read"):
            bus.sync_read("Present_Position", [1])
        assert client.empty_reads == 8 * 101
        sim.silent_ids.clear()
        assert bus.read("Present_Position", 1) == 1000  # nothing stale left behind


def test_only_servos_at_the_ports_baud_rate_answer() -> None:
    servo = SimServo(1, "sts3215", 700.0)
    servo.set_reg("Baud_Rate", 4)  # 115 200 bit/s
    with SimServoBus([servo], transport="inproc") as sim:
        with FeetechBus(sim.port, {1: "sts3215"}, retries=0) as bus, pytest.raises(CalibTimeoutError):
            bus.read("Present_Position", 1)
        assert sim.client_baudrate() is None  # closed with the bus
        with FeetechBus(sim.port, {1: "sts3215"}, baudrate=115_200, retries=0) as bus:
            assert bus.read("Present_Position", 1) == 700
            assert sim.client_baudrate() == 115_200


def test_the_sdk_runs_in_the_callers_thread_and_no_thread_or_pty_is_started() -> None:
    before = threading.active_count()
    with SimServoBus([SimServo(1, "sts3215", 10.0)], transport="inproc") as sim:
        assert sim.port.startswith("inproc://sim-servo-")
        assert threading.active_count() == before
        with FeetechBus(sim.port, {1: "sts3215"}) as bus:
            assert bus.read("Present_Position", 1) == 10
            handler = bus._port_handler
            assert isinstance(handler, scs.PortHandler) and isinstance(handler.ser, InProcessSerial)
        port = sim.port
    assert inproc_serial.lookup(port) is None  # unregistered when the simulator stops


def test_a_port_nobody_answers_and_a_closed_port_are_device_errors() -> None:
    with pytest.raises(DeviceError, match=r"inproc://nobody-1: no in-process port of that name"):
        FeetechBus("inproc://nobody-1", {1: "sts3215"})
    with SimServoBus([SimServo(1, "sts3215", 10.0)], transport="inproc") as sim:
        bus = FeetechBus(sim.port, {1: "sts3215"})
        bus._port_handler.ser.close()  # as if the port went away under the SDK
        with pytest.raises(DeviceError, match="the in-process port is closed"):
            bus.read("Present_Position", 1)
    with pytest.raises(UsageError, match="transport 'tcp': expected one of pty, inproc"):
        SimServoBus([SimServo(1, "sts3215")], transport="tcp")
