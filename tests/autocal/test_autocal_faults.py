"""A device fault during the stop search ends the run (issue 11): every motor limp, nothing written, exit 3.

The fault comes over the real wire from the simulated firmware in the middle of a search: a Robstride
over-temperature bit in the type-2 feedback, a Feetech ``Status`` over-temperature bit, a Dynamixel
``Hardware_Error_Status`` overheating bit (robocal reads the servo's bit twice before it believes it).
"""

from __future__ import annotations

import dataclasses
import re
from pathlib import Path
from typing import Any

import pytest

pytest.importorskip("can")

from robocal.backends.robstride.sim import SimMotor
from robocal.backends.sim.lite import lite_urdf_text
from robocal.cli.main import main
from robocal.workflows.autocal.job import AutoCalAbortedError
from robocal.workflows.autocal.sim import SimAutoLite, open_sim_lite
from robocal.workflows.lerobot import robot_spec
from robocal.workflows.lerobot.auto import (
    AutoCalibrationRequest,
    auto_calibrate,
    auto_section,
    search_registers,
)
from robocal.workflows.lerobot.auto_sim import open_auto_arm

pytestmark = pytest.mark.timeout(600)

PRIOR = "left_wrist_roll:\n  id: 16\n  direction: -1\n  homing_offset: 0.25\n"
OVER_TEMPERATURE = 1 << 2  # Robstride type-2 fault field: bit 18 of the identifier


def test_lite_motor_fault_limp_nothing_written_exit_3(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    urdf = tmp_path / "lite.urdf"
    urdf.write_text(lite_urdf_text())
    out, report = tmp_path / "cal.yaml", tmp_path / "r.json"
    out.write_text(PRIOR)
    sims: list[SimAutoLite] = []
    frames = {"n": 0}
    original = SimMotor.feedback

    def hot_after_200(self: SimMotor, host_id: int) -> Any:
        fb = original(self, host_id)
        if self.can_id == 16 and self.mode == 2:  # left_wrist_roll, in MIT mode
            frames["n"] += 1
            if frames["n"] > 200:
                return dataclasses.replace(fb, faults=fb.faults | OVER_TEMPERATURE)
        return fb

    def keep(*args: Any, **kwargs: Any) -> SimAutoLite:
        sims.append(open_sim_lite(*args, **kwargs))
        return sims[-1]

    monkeypatch.setattr(SimMotor, "feedback", hot_after_200)
    monkeypatch.setattr("robocal.workflows.autocal.sim.open_sim_lite", keep)
    rc = main(
        ["sweep", "--auto", "--urdf", str(urdf), "--robot", "bhl_arms", "--source", "sim:lite?seed=2",
         "--out", str(out), "--report", str(report), "--joints", "left_wrist_roll,left_wrist_pitch", "--yes"]
    )  # fmt: skip
    err = capsys.readouterr().err
    assert rc == 3
    assert err.count("error:") == 1 and "motor fault bits 0x04" in err and "every motor limp" in err
    assert out.read_text() == PRIOR and not report.exists()
    assert frames["n"] > 200
    assert all(m.mode == 0 and m.drive().tau_max_nm == 0.0 for m in sims[0].motors.values())


def _registers(arm: Any, spec: Any) -> dict[str, dict[str, int]]:
    out = {}
    for m in spec.motors:
        servo = arm.sim.servo(m.name)
        out[m.name] = {
            n: servo.get_reg(n) for n in (*search_registers(arm.bus, spec, m.motor_id), "Torque_Enable")
        }
    return out


class _FaultAt:
    """A live view that sets a fault register on the simulated servo at the ``at``-th reading."""

    def __init__(self, arm: Any, joint: str, register: str, bits: int, at: int = 60) -> None:
        self.arm, self.joint, self.register, self.bits, self.at = arm, joint, register, bits, at
        self.samples = 0

    def joint_start(self, name: str, cap_nm: float, speed_rad_s: float) -> None:
        pass

    def sample(self, name: str, phase: str, side: str, sample: Any) -> None:
        self.samples += 1
        if self.samples == self.at:
            servo = self.arm.sim.servo(self.joint)
            with self.arm.sim.bus.lock:
                servo.set_reg(self.register, servo.get_reg(self.register) | self.bits)

    def joint_done(self, outcome: Any) -> None:
        pass


@pytest.mark.slow
@pytest.mark.parametrize(
    ("robot", "register", "bits", "message"),
    [
        ("so101_follower", "Status", 0x04, "Status 0x04 (voltage, sensor or temperature)"),
        ("koch_follower", "Hardware_Error_Status", 0x04, "Hardware_Error_Status 0x04"),
    ],
)
def test_servo_fault_limp_eeprom_restored_nothing_written(
    tmp_path: Path, robot: str, register: str, bits: int, message: str
) -> None:
    spec = robot_spec(robot)
    section = auto_section(robot)
    out = tmp_path / "cal.json"
    with open_auto_arm(spec, "sim", section) as arm:
        before = _registers(arm, spec)
        view = _FaultAt(arm, "gripper", register, bits)
        with pytest.raises(AutoCalAbortedError, match=re.escape(message)) as info:
            auto_calibrate(
                arm.bus,
                AutoCalibrationRequest(
                    spec,
                    section,
                    path=out,
                    joints=["gripper"],
                ),
                clock=arm.clock,
                view=view,
            )
        arm.sim.servo("gripper").set_reg(register, 0)  # the fault was the test's; the rest must be as before
        after = _registers(arm, spec)
    assert info.value.exit_code == 3 and "every motor limp" in str(info.value)
    assert after == before and not out.exists()
    assert {r["Torque_Enable"] for r in after.values()} == {0}
