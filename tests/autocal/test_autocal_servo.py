"""LeRobot arms find their own hard stops: the Feetech / Dynamixel stop-search drivers over the real SDKs.

Every test runs the unmodified vendor SDK (through robocal's FeetechBus / DynamixelBus) against the simulated
firmware with physics on a pseudo-terminal (``open_auto_arm(spec, "sim...")``), on a simulated clock.
"""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

import pytest

from robocal.backends.dynamixel.joint_driver import DynamixelJointDriver
from robocal.backends.feetech.joint_driver import FeetechJointDriver
from robocal.core.lerobot import MotorCalibration
from robocal.errors import UsageError
from robocal.workflows.autocal.job import AutoCalFailedError
from robocal.workflows.lerobot import robot_spec
from robocal.workflows.lerobot.auto import (
    AutoCalibrationRequest,
    auto_calibrate,
    auto_section,
    search_registers,
)
from robocal.workflows.lerobot.auto_sim import open_auto_arm

pytestmark = pytest.mark.timeout(600)


def registers(arm: Any, spec: Any) -> dict[str, dict[str, int]]:
    """Every register a search may change, read straight from the simulated servos (no bus traffic)."""
    out = {}
    for m in spec.motors:
        servo = arm.sim.servo(m.name)
        names = [*search_registers(arm.bus, spec, m.motor_id), "Torque_Enable"]
        out[m.name] = {n: servo.get_reg(n) for n in names}
    return out


class Recorder:
    """A live view that records the searches (and can press Ctrl-C at a chosen sample)."""

    def __init__(self, interrupt_at: int | None = None) -> None:
        self.started: list[tuple[str, float]] = []
        self.samples = 0
        self.done: list[str] = []
        self.interrupt_at = interrupt_at

    def joint_start(self, name: str, cap_nm: float, speed_rad_s: float) -> None:
        self.started.append((name, cap_nm))

    def sample(self, name: str, phase: str, side: str, sample: Any) -> None:
        self.samples += 1
        if self.interrupt_at is not None and self.samples >= self.interrupt_at:
            raise KeyboardInterrupt

    def joint_done(self, outcome: Any) -> None:
        self.done.append(outcome.name)


@pytest.mark.slow
def test_so101_finds_its_stops_through_the_feetech_registers(tmp_path: Path) -> None:
    spec = robot_spec("so101_follower")
    section = auto_section("so101_follower")
    out = tmp_path / "so101.json"
    view = Recorder()
    with open_auto_arm(spec, "sim", section) as arm:
        before = registers(arm, spec)
        res = auto_calibrate(
            arm.bus,
            AutoCalibrationRequest(
                spec,
                section,
                path=out,
                joints=["wrist_flex", "elbow_flex"],
            ),
            clock=arm.clock,
            view=view,
        )
        after = registers(arm, spec)
        truth = arm.sim.truth
        recovered = arm.sim.recovered_stops(res.calibration)
        eeprom = arm.sim.eeprom()
    assert [n for n, _ in view.started] == ["elbow_flex", "wrist_flex"]  # the profile's order
    assert view.started[0][1] == pytest.approx(0.4 * 1.91)  # elbow_flex: 40 % of the 7.4 V STS3215
    assert res.exit_code == 0 and res.path == out
    for name in ("elbow_flex", "wrist_flex"):
        lo, hi = recovered[name]
        t = truth[name]
        # the contact surfaces, within 2 ticks (0.18°) of the simulated stops (wrist_flex across the seam)
        assert (lo - t.stop_low_ticks + 2048) % 4096 - 2048 == pytest.approx(0, abs=2)
        assert (hi - t.stop_high_ticks + 2048) % 4096 - 2048 == pytest.approx(0, abs=2)
        c = res.calibration[name]
        assert (c.range_min + c.range_max) // 2 in (2046, 2047, 2048)  # homing: the middle reads half a turn
        assert eeprom[name] == {
            "Homing_Offset": c.homing_offset,
            "Min_Position_Limit": c.range_min,
            "Max_Position_Limit": c.range_max,
        }
        # the search's RAM values and mode are back; torque off
        assert {k: v for k, v in after[name].items() if k not in eeprom[name]} == {
            k: v for k, v in before[name].items() if k not in eeprom[name]
        }
    assert res.kept == ("shoulder_pan", "shoulder_lift", "wrist_roll", "gripper")
    for name in res.kept:
        assert after[name] == before[name]
    # LeRobot's file: every motor, the manual procedure's keys
    doc = json.loads(out.read_text())
    assert list(doc) == list(spec.motor_names)
    assert set(doc["elbow_flex"]) == {"id", "drive_mode", "homing_offset", "range_min", "range_max"}
    assert MotorCalibration(**doc["wrist_flex"]) == res.calibration["wrist_flex"]


@pytest.mark.slow
def test_feetech_search_across_the_seam_rehomes_wrist_roll() -> None:
    spec = robot_spec("so101_follower")
    section = auto_section("so101_follower")
    with open_auto_arm(spec, "sim?seed=2", section) as arm:
        res = auto_calibrate(
            arm.bus,
            AutoCalibrationRequest(
                spec,
                section,
                joints=["wrist_roll"],
                sweep_full_turn=True,
            ),
            clock=arm.clock,
        )
        truth = arm.sim.truth["wrist_roll"]
        lo, hi = arm.sim.recovered_stops(res.calibration)["wrist_roll"]
    stops = res.auto["wrist_roll"].stops
    assert math.degrees(stops.span_rad) == pytest.approx(
        (truth.stop_high_ticks - truth.stop_low_ticks) * 360 / 4096, abs=0.3
    )  # ~340°: more than half a turn, so the joint was re-homed on the way
    assert (lo - truth.stop_low_ticks + 2048) % 4096 - 2048 == pytest.approx(0, abs=2)
    assert (hi - truth.stop_high_ticks + 2048) % 4096 - 2048 == pytest.approx(0, abs=2)


@pytest.mark.slow
def test_koch_current_based_and_pwm_capped_dynamixels(tmp_path: Path) -> None:
    spec = robot_spec("koch_follower")
    section = auto_section("koch_follower")
    with open_auto_arm(spec, "sim", section) as arm:
        res = auto_calibrate(
            arm.bus,
            AutoCalibrationRequest(
                spec,
                section,
                path=tmp_path / "k.json",
                joints=["shoulder_lift", "gripper"],
            ),
            clock=arm.clock,
        )
        truth = arm.sim.truth
        recovered = arm.sim.recovered_stops(res.calibration)
        modes = {m.name: arm.sim.servo(m.name).get_reg("Operating_Mode") for m in spec.motors}
    for name in ("shoulder_lift", "gripper"):  # XL430 (Goal_PWM cap, mode 4) and XL330 (Goal_Current, mode 5)
        lo, hi = recovered[name]
        assert lo == pytest.approx(truth[name].stop_low_ticks, abs=3)
        assert hi == pytest.approx(truth[name].stop_high_ticks, abs=3)
    assert modes["gripper"] == 4 and modes["shoulder_lift"] == 4  # the profile's mode again (LeRobot: 4)
    assert res.calibration["gripper"].drive_mode == 0


@pytest.mark.slow
def test_missing_stop_fails_the_joint_and_writes_nothing(tmp_path: Path) -> None:
    spec = robot_spec("so101_follower")
    section = auto_section("so101_follower")
    out = tmp_path / "cal.json"
    with open_auto_arm(spec, "sim?missing=gripper", section) as arm:
        before = registers(arm, spec)
        with pytest.raises(AutoCalFailedError, match=r"gripper: missing_stop .*nothing was written") as err:
            auto_calibrate(
                arm.bus,
                AutoCalibrationRequest(
                    spec,
                    section,
                    path=out,
                    joints=["gripper"],
                ),
                clock=arm.clock,
            )
        after = registers(arm, spec)
    assert err.value.exit_code == 3
    assert err.value.result["gripper"].stops.code == "missing_stop"
    assert after == before and not out.exists()


@pytest.mark.slow
@pytest.mark.parametrize(
    "at", [2, 120, pytest.param(700, marks=pytest.mark.slow)]
)  # before contact, pressed into the lower stop, on the upper side
def test_ctrl_c_limps_every_motor_and_restores_every_register(tmp_path: Path, at: int) -> None:
    spec = robot_spec("so101_follower")
    section = auto_section("so101_follower")
    out = tmp_path / "cal.json"
    with open_auto_arm(spec, "sim", section) as arm:
        arm.bus.write("Torque_Limit", 3, 777)  # a user's RAM setting survives
        before = registers(arm, spec)
        view = Recorder(interrupt_at=at)
        with pytest.raises(KeyboardInterrupt):
            auto_calibrate(
                arm.bus,
                AutoCalibrationRequest(
                    spec,
                    section,
                    path=out,
                    joints=["gripper", "elbow_flex"],
                ),
                clock=arm.clock,
                view=view,
            )
        after = registers(arm, spec)
        torque = {m.name: arm.sim.servo(m.name).get_reg("Torque_Enable") for m in spec.motors}
    assert view.samples == at
    assert after == before and not out.exists()
    assert set(torque.values()) == {0}


def test_driver_types_per_vendor() -> None:
    spec = robot_spec("koch_follower")
    section = auto_section("koch_follower")
    from robocal.workflows.autocal.model import joint_driver_class

    with open_auto_arm(spec, "sim", section) as arm:
        d = joint_driver_class("dynamixel")(arm.bus, "elbow_flex", 3, rated_nm=0.52, cap_nm=0.13, clock=arm.clock)
        assert isinstance(d, DynamixelJointDriver) and d.operating_mode == 5
        d2 = joint_driver_class("dynamixel")(arm.bus, "shoulder_lift", 2, rated_nm=1.4, cap_nm=0.42, clock=arm.clock)
        assert isinstance(d2, DynamixelJointDriver) and d2.operating_mode == 4
        s = d.read()
        assert s.ok and s.q_rad == pytest.approx(2100 * 2 * math.pi / 4096)
    assert FeetechJointDriver.__mro__[1] is DynamixelJointDriver.__mro__[1]
    assert joint_driver_class("feetech") is FeetechJointDriver
    with pytest.raises(UsageError, match="unknown vendor 'nosuch'"):
        joint_driver_class("nosuch")


@pytest.mark.slow
def test_obstacle_near_the_transit_end_is_a_span_mismatch_not_an_abort() -> None:
    # the simulated block sits 1.25° short of where the fast transit ends: held short of its target at the cap
    spec = robot_spec("so101_follower")
    section = auto_section("so101_follower")
    with open_auto_arm(spec, "sim?obstacle=gripper", section) as arm:
        before = registers(arm, spec)
        with pytest.raises(
            AutoCalFailedError,
            match=r"gripper: span_mismatch \(span 9\d\.\d° differs from the expected 125\.0°",
        ):
            auto_calibrate(
                arm.bus,
                AutoCalibrationRequest(
                    spec,
                    section,
                    joints=["gripper"],
                ),
                clock=arm.clock,
            )
        assert registers(arm, spec) == before


@pytest.mark.slow
def test_dynamixel_overload_shutdown_is_rebooted_and_the_search_goes_on() -> None:
    spec = robot_spec("koch_follower")
    section = auto_section("koch_follower")
    flagged: list[int] = []

    with open_auto_arm(spec, "sim", section) as arm:
        servo = arm.sim.servo("gripper")

        class Latch(Recorder):
            def sample(self, name: str, phase: str, side: str, sample: Any) -> None:
                super().sample(name, phase, side, sample)
                if sample.overload:
                    flagged.append(self.samples)
                if (
                    self.samples == 60
                ):  # the firmware's overload shutdown: torque off, error bit until a REBOOT
                    with arm.sim.bus.lock:
                        servo.set_reg("Hardware_Error_Status", 0x20)
                        servo.set_reg("Torque_Enable", 0)

        res = auto_calibrate(
            arm.bus,
            AutoCalibrationRequest(
                spec,
                section,
                joints=["gripper"],
            ),
            clock=arm.clock,
            view=Latch(),
        )
        lo, hi = arm.sim.recovered_stops(res.calibration)["gripper"]
        errors = servo.get_reg("Hardware_Error_Status")
    assert flagged and flagged[0] == 61  # the next reading carries the flag; the REBOOT then clears it
    assert res.auto["gripper"].ok and errors == 0
    assert (lo, hi) == pytest.approx((2000, 3000), abs=3)


@pytest.mark.slow
def test_feetech_silent_at_the_stop_is_confirmed_by_a_reread() -> None:
    spec = robot_spec("so101_follower")
    section = auto_section("so101_follower")
    with open_auto_arm(spec, "sim?silent=gripper", section) as arm:
        res = auto_calibrate(
            arm.bus,
            AutoCalibrationRequest(
                spec,
                section,
                joints=["gripper"],
            ),
            clock=arm.clock,
        )
        lo, hi = arm.sim.recovered_stops(res.calibration)["gripper"]
    stops = res.auto["gripper"].stops
    assert (stops.lower.test, stops.upper.test) == ("no-reply+reread", "no-reply+reread")  # type: ignore[union-attr]
    assert (lo, hi) == pytest.approx((2000, 3400), abs=2)


def test_not_confirmed_nothing_moves() -> None:
    spec = robot_spec("koch_follower")
    section = auto_section("koch_follower")
    asked: list[tuple[tuple[str, ...], dict[str, float]]] = []

    def confirm(names: Any, caps: Any) -> bool:
        asked.append((tuple(names), dict(caps)))
        return False

    with open_auto_arm(spec, "sim", section) as arm:
        before = registers(arm, spec)
        instructions = arm.sim.bus.instructions
        with pytest.raises(Exception, match="not confirmed: nothing moved, nothing written"):
            auto_calibrate(
                arm.bus,
                AutoCalibrationRequest(
                    spec,
                    section,
                ),
                clock=arm.clock,
                confirm_start=confirm,
            )
        assert arm.sim.bus.instructions == instructions  # not one packet sent
        assert registers(arm, spec) == before
    assert asked[0][0] == ("shoulder_lift", "elbow_flex", "wrist_flex", "gripper")
    assert asked[0][1]["shoulder_lift"] == pytest.approx(0.42) and asked[0][1]["gripper"] == pytest.approx(
        0.13
    )


@pytest.mark.slow
def test_ctrl_c_while_the_calibration_is_written_restores_it(tmp_path: Path) -> None:
    spec = robot_spec("so101_follower")
    section = auto_section("so101_follower")
    out = tmp_path / "cal.json"

    class CtrlCOnThirdLimit:
        """The arm's bus, but Ctrl-C arrives at the third Max_Position_Limit write (the final EEPROM plan)."""

        def __init__(self, bus: Any) -> None:
            self._bus = bus
            self.limit_writes = 0

        def __getattr__(self, name: str) -> Any:
            return getattr(self._bus, name)

        def write(self, register: str, motor_id: int, value: int) -> None:
            if register == "Max_Position_Limit":
                self.limit_writes += 1
                if self.limit_writes == 3:
                    raise KeyboardInterrupt
            self._bus.write(register, motor_id, value)

    with open_auto_arm(spec, "sim", section) as arm:
        before = registers(arm, spec)
        bus = CtrlCOnThirdLimit(arm.bus)
        with pytest.raises(KeyboardInterrupt):
            auto_calibrate(
                bus,
                AutoCalibrationRequest(
                    spec,
                    section,
                    path=out,
                    joints=["gripper"],
                ),
                clock=arm.clock,
            )  # type: ignore[arg-type]
        assert bus.limit_writes >= 3
        assert registers(arm, spec) == before and not out.exists()
