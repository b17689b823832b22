"""``--verify``'s resolution term is one count of each vendor's own position reading (issue 30 item 2).

The uncertainty of a drift is ``hypot(span term, one count)``; one count is the vendor's: a turn over 4096 on the
Feetech STS and Dynamixel X servos, ``2·P_MAX / 65535`` of the 16-bit MIT reply on the CAN motors (Robstride ±4π on
every model; Damiao its PMAX register, 12.5 rad on the OpenArm's models unless the motor says otherwise).
"""

from __future__ import annotations

import dataclasses
import math
from types import SimpleNamespace

import pytest

from robocal.backends.clock import MonotonicClock
from robocal.backends.damiao.joint_driver import DamiaoJointDriver
from robocal.backends.damiao.tables import model_limits
from robocal.backends.dynamixel.joint_driver import DynamixelJointDriver
from robocal.backends.feetech.joint_driver import FeetechJointDriver
from robocal.backends.robstride.joint_driver import RobstrideJointDriver
from robocal.core.health.drift import offset_drift


def _servo_bus(model: str) -> SimpleNamespace:
    return SimpleNamespace(motors={1: model}, resolution=lambda motor_id: 4096)


@pytest.mark.parametrize(
    ("driver", "model"), [(FeetechJointDriver, "sts3215"), (DynamixelJointDriver, "xl430-w250")]
)
def test_a_servo_count_is_a_turn_over_4096(driver: type, model: str) -> None:
    d = driver(_servo_bus(model), "j", 1, rated_nm=1.0, cap_nm=0.3, clock=MonotonicClock())
    assert d.position_count_rad() == pytest.approx(2 * math.pi / 4096, rel=1e-12)
    assert math.degrees(d.position_count_rad()) == pytest.approx(0.08789, abs=1e-5)


def test_a_robstride_count_is_8_pi_over_65535_on_every_model() -> None:
    for model in ("RS00", "RS03", "RS06"):
        bus = SimpleNamespace(motors={"j": SimpleNamespace(model=model)})
        d = RobstrideJointDriver(bus, "j", 1, 1.0, math.radians(3), MonotonicClock())
        assert d.position_count_rad() == pytest.approx(8 * math.pi / 65535, rel=1e-12)
        assert math.degrees(d.position_count_rad()) == pytest.approx(0.021973, abs=1e-6)


def test_a_damiao_count_follows_the_motors_pmax() -> None:
    bus = SimpleNamespace(motors={"j": SimpleNamespace(model="DM4310")}, limits={"j": model_limits("DM4310")})
    d = DamiaoJointDriver(bus, "j", 1, 1.0, math.radians(3), MonotonicClock())
    assert d.position_count_rad() == pytest.approx(25.0 / 65535, rel=1e-12)  # PMAX 12.5 rad
    assert math.degrees(d.position_count_rad()) == pytest.approx(0.021857, abs=1e-6)
    bus.limits["j"] = dataclasses.replace(bus.limits["j"], p_max_rad=math.pi)  # a PMAX register set to π
    assert d.position_count_rad() == pytest.approx(2 * math.pi / 65535, rel=1e-12)
    drift = offset_drift("j", 1, 0.1, 0.1, 0.0, d.position_count_rad(), 2.0)
    assert drift.uncertainty_deg == pytest.approx(360 / 65535, rel=1e-9)  # no span term: one count alone
