"""The hand calibration (``lerobot calibrate``, not ``--auto``) restores every register it changed (issue 26 item 1).

The procedure writes Operating_Mode, clears Phase bit 4 (Feetech STS) and unlocks the EEPROM (``Lock`` 0) besides the
calibration registers. Judged by the simulated servos' registers: after a Ctrl-C each one is byte-equal to before;
after a finished run the EEPROM ``Lock`` is back as it was.
"""

from __future__ import annotations

from pathlib import Path

import pytest

from robocal.backends.sim.lerobot_arms import SimArm, SimArmOperator
from robocal.workflows.lerobot import CalibrateRequest, calibrate, open_bus, robot_spec

from .conftest import PREVIOUS

pytestmark = pytest.mark.timeout(120)

# registers the procedure changes besides the calibration EEPROM, set to values it would change
ODD = {
    "so101_follower": {"Operating_Mode": 3, "Phase": 0x1C, "Lock": 1},
    "koch_leader": {"Operating_Mode": 3},
}


def _registers(arm: SimArm, names: tuple[str, ...]) -> dict[str, dict[str, int]]:
    out = {}
    for m in arm.spec.motors:
        servo = arm.servo(m.name)
        out[m.name] = {n: servo.get_reg(n) for n in names if n in servo.table}
    return out


def _arm(robot: str) -> SimArm:
    arm = SimArm(robot_spec(robot), eeprom=PREVIOUS[robot]).start()
    for m in arm.spec.motors:
        for reg, value in ODD[robot].items():
            arm.servo(m.name).set_reg(reg, value)
    return arm


NAMES = ("Homing_Offset", "Min_Position_Limit", "Max_Position_Limit", "Drive_Mode", "Operating_Mode", "Phase", "Lock")


@pytest.mark.parametrize("robot", ["so101_follower", "koch_leader"])
@pytest.mark.parametrize("where", [{"interrupt_at_step": 3}, {"interrupt_at_prompt": "sweep"}])
def test_ctrl_c_restores_operating_mode_phase_and_lock(
    tmp_path: Path, robot: str, where: dict[str, object]
) -> None:
    arm = _arm(robot)
    bus = open_bus(arm.spec, arm.port)
    try:
        before = _registers(arm, NAMES)
        assert all(r["Operating_Mode"] == 3 for r in before.values())
        with pytest.raises(KeyboardInterrupt):
            calibrate(bus, CalibrateRequest(arm.spec, path=tmp_path / "c.json"), SimArmOperator(arm, **where))  # type: ignore[arg-type]
        assert _registers(arm, NAMES) == before
        assert all(arm.servo(m.name).get_reg("Torque_Enable") == 0 for m in arm.spec.motors)
        assert not (tmp_path / "c.json").exists()
    finally:
        bus.close()
        arm.stop()


def test_a_finished_run_locks_the_eeprom_again(tmp_path: Path) -> None:
    arm = _arm("so101_follower")
    bus = open_bus(arm.spec, arm.port)
    try:
        result = calibrate(bus, CalibrateRequest(arm.spec, path=tmp_path / "c.json"), SimArmOperator(arm))
        after = _registers(arm, NAMES)
        assert {r["Lock"] for r in after.values()} == {1}
        assert {r["Operating_Mode"] for r in after.values()} == {0}  # LeRobot's position mode: meant to change
        assert {r["Phase"] for r in after.values()} == {0x0C}  # bit 4 cleared: meant to change
        for name, cal in result.calibration.items():
            assert after[name]["Homing_Offset"] == cal.homing_offset
    finally:
        bus.close()
        arm.stop()
