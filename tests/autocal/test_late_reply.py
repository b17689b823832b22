"""A status packet that arrives after its read timed out must not answer the next read (the vendor SDKs'
``clearPort`` only flushes the output; robocal's buses empty the input before each packet).

Under load a simulated (or real) servo may answer after the SDK gave up; the next read then took that late
packet — a block read's first byte as a one-byte register — and the stop search saw an impossible
``Hardware_Error_Status`` (0x7b, 0xb8) and aborted the run.
"""

from __future__ import annotations

import time

import pytest

from robocal.backends.sim.lerobot_arms import SimArm
from robocal.backends.sim.servo_packets import dynamixel_status, feetech_status
from robocal.workflows.lerobot import robot_spec
from robocal.workflows.lerobot.arms import open_bus

pytestmark = pytest.mark.timeout(120)


@pytest.mark.parametrize(
    ("robot", "register", "status"),
    [
        ("koch_follower", "Hardware_Error_Status", dynamixel_status),
        ("so101_follower", "Status", feetech_status),
    ],
)
def test_a_late_status_packet_is_not_taken_as_the_next_reply(robot: str, register: str, status: object) -> None:
    spec = robot_spec(robot)
    motor = spec.motors[2]
    with SimArm(spec) as arm:
        bus = open_bus(spec, arm.port)
        try:
            assert bus.sync_read(register, [motor.motor_id])[motor.motor_id] == 0
            # a late reply (valid checksum, the same motor) waiting in the host's input
            late = status(motor.motor_id, 0, bytes([0x7B, 0x00, 0x10, 0x00]))  # type: ignore[operator]
            arm.bus._send(late)
            ser = bus._port_handler.ser  # type: ignore[attr-defined]
            deadline = time.monotonic() + 60  # a hang guard: the pty hands bytes on when the kernel gets to it
            while ser.in_waiting < len(late):  # until the late reply is in the host's input, however loaded
                assert time.monotonic() < deadline, "the late reply never reached the host"
                time.sleep(0.01)
            assert bus.sync_read(register, [motor.motor_id])[motor.motor_id] == 0
            assert bus.read("Present_Position", motor.motor_id) == bus.read("Present_Position", motor.motor_id)
        finally:
            bus.close()
