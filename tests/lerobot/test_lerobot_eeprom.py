"""robocal.workflows.lerobot.eeprom: restore checks every value before writing any."""

from __future__ import annotations

import pytest

from robocal.lerobot import MotorCalibration
from robocal.workflows.lerobot import robot_spec

pytestmark = pytest.mark.timeout(60)


# ---------------------------------------------------------------------------------------- restore / check
@pytest.mark.parametrize(
    ("robot", "motor", "field", "value", "message"),
    [
        ("so101_follower", "wrist_roll", "homing_offset", 5000, "Magnitude 5000 exceeds 2047"),
        ("so101_follower", "gripper", "range_max", 70000, "value 70000 does not fit register"),
        ("koch_leader", "gripper", "range_min", -5, "value -5 does not fit register 'Min_Position_Limit'"),
    ],
)
def test_restore_validates_every_value_before_writing_any(
    robot: str, motor: str, field: str, value: int, message: str
) -> None:
    from dataclasses import replace

    from robocal.backends.sim.lerobot_arms import SimArm
    from robocal.errors import CalibError
    from robocal.workflows.lerobot import open_bus, restore

    with SimArm(robot_spec(robot)) as arm:
        cals = {m.name: MotorCalibration(m.motor_id, 0, 7, 100, 4000) for m in arm.spec.motors}
        cals[motor] = replace(cals[motor], **{field: value})
        before = arm.eeprom()
        torque = {m.name: arm.servo(m.name).get_reg("Torque_Enable") for m in arm.spec.motors}
        bus = open_bus(arm.spec, arm.port)
        try:
            with pytest.raises(CalibError, match=message):
                restore(bus, arm.spec, cals)
        finally:
            bus.close()
        assert arm.eeprom() == before
        assert {m.name: arm.servo(m.name).get_reg("Torque_Enable") for m in arm.spec.motors} == torque
