"""A Feetech re-home whose Homing_Offset write loses its status packet: the offset is read back, never assumed."""

from __future__ import annotations

import math
from collections.abc import Sequence

import pytest

from robocal.backends.feetech.joint_driver import FeetechJointDriver
from robocal.backends.sim.physics import SimClock
from robocal.errors import CalibTimeoutError, DeviceError

from .bench_loader import load_benchmark

RES = 4096


class _LossyBus:
    """A Feetech bus stand-in: one STS3215 whose Homing_Offset write is applied but its status packet lost."""

    def __init__(self, actual_ticks: int, *, answers_read_back: bool) -> None:
        self.motors = {1: "sts3215"}
        self.actual = actual_ticks
        self.offset = 0
        self.answers_read_back = answers_read_back

    def resolution(self, motor_id: int) -> int:
        return RES

    def sync_write(self, register: str, values: dict[int, int]) -> None:
        pass

    def sync_read_block(
        self, registers: Sequence[str], motor_ids: Sequence[int]
    ) -> dict[int, dict[str, int]]:
        present = (self.actual - self.offset) % RES
        return {1: {"Present_Position": present, "Present_Velocity": 0, "Present_Load": 0, "Status": 0}}

    def sync_read(self, register: str, motor_ids: Sequence[int]) -> dict[int, int]:
        return {1: self.sync_read_block([register], motor_ids)[1][register]}

    def write(self, register: str, motor_id: int, value: int) -> None:
        assert register == "Homing_Offset"
        self.offset = value  # applied ...
        raise CalibTimeoutError("motor 1: write 'Homing_Offset' failed after 4 tries")  # ... but no status

    def read(self, register: str, motor_id: int) -> int:
        assert register == "Homing_Offset"
        if not self.answers_read_back:
            raise CalibTimeoutError("motor 1: read 'Homing_Offset' failed after 4 tries")
        return self.offset


def _driver(bus: _LossyBus) -> FeetechJointDriver:
    return FeetechJointDriver(bus, "shoulder_pan", 1, rated_nm=1.91, cap_nm=0.48, clock=SimClock())


def test_the_offset_the_servo_holds_is_read_back_and_the_position_does_not_jump() -> None:
    bus = _LossyBus(3585, answers_read_back=True)
    drv = _driver(bus)
    before = drv.read().q_rad
    drv.rehome()
    assert drv.homing_offset == bus.offset == 3585 - 2047
    assert drv.read().q_rad == pytest.approx(before, abs=1e-12)  # before the fix: 135° off (the old offset)


def test_a_servo_that_does_not_answer_the_read_back_ends_the_search_as_a_device_fault() -> None:
    drv = _driver(_LossyBus(3585, answers_read_back=False))
    drv.read()
    with pytest.raises(
        DeviceError, match=r"joint shoulder_pan: motor 1 did not confirm its new Homing_Offset"
    ):
        drv.rehome()


@pytest.mark.slow
def test_so101_pan_silent_at_its_stop_while_re_homing_finds_both_stops() -> None:
    """Found by 100 seeded runs per joint on the servo firmware sim: seed 48 of the SO-101's shoulder_pan re-homes
    next to its upper stop while the motor is silent; the Homing_Offset write was applied without a status packet,
    the driver kept the old offset, the position jumped by 135° and the search ended as ``missing_stop``."""
    bench = load_benchmark("bench_autocal_servo")
    spec = next(s for s in bench.SERVO_SCENARIOS if s.name == "silent_at_stop")
    run = bench.run_one("so101_follower", spec, 48, "shoulder_pan")
    assert run.code == "ok"
    assert run.tests == ("no-reply+reread", "no-reply+reread")
    assert abs(run.zero_err_deg) < 0.5 and abs(run.span_err_deg) < 1.0
    assert math.isfinite(run.zero_err_deg)
