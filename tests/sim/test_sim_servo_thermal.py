"""Present_Temperature rises and the supply voltage sags with the current (issue 29 item 1, assumed model)."""

from __future__ import annotations

import math

import pytest

from robocal.backends.dynamixel import DynamixelBus
from robocal.backends.feetech import FeetechBus
from robocal.backends.sim.physics import JointPlant
from robocal.backends.sim.servo_thermal import ServoThermal

from .test_sim_servo_physics import STS, TICK, XL, ZERO, params, rig, wait

pytestmark = pytest.mark.timeout(120)

# The model's assumed numbers, restated: 50 °C above ambient at the stall current, τ = 300 s, 0.2 Ω source.
RISE_C, TAU_S, R_OHM = 50.0, 300.0, 0.2


def expected_c(fraction_of_stall: float, held_s: float) -> float:
    return 25.0 + RISE_C * fraction_of_stall**2 * (1.0 - math.exp(-held_s / TAU_S))


def test_model_is_first_order_and_independent_of_the_read_rate() -> None:
    once = ServoThermal(ambient_c=25.0, supply_v=7.4, stall_current_a=2.0, t_s=0.0)
    often = ServoThermal(ambient_c=25.0, supply_v=7.4, stall_current_a=2.0, t_s=0.0)
    once.update(300.0, 2.0)
    for k in range(1, 301):
        often.update(float(k), -2.0)  # the sign of the current does not matter
    assert once.temperature_c == pytest.approx(25.0 + 50.0 * (1 - math.exp(-1)), abs=1e-12)
    assert often.temperature_c == pytest.approx(once.temperature_c, abs=1e-9)
    assert once.voltage_v == pytest.approx(7.4 - 0.4, abs=1e-12)
    once.update(300.0 + 3000.0, 0.0)  # cooling back to ambient
    assert once.temperature_c == pytest.approx(25.0, abs=0.01)
    assert once.voltage_v == 7.4


def test_feetech_stall_warms_the_servo_and_sags_its_voltage() -> None:
    plant = JointPlant(params(), q0_rad=0.9)
    with rig("sts3215", plant, 0.9) as (_servo, clock, bus):
        assert isinstance(bus, FeetechBus)
        assert (bus.read("Present_Temperature", 1), bus.read("Present_Voltage", 1)) == (25, 74)
        bus.write("Torque_Limit", 1, 700)  # 70 % of the stall torque: below the 80 % overload threshold
        bus.write("Torque_Enable", 1, 1)
        bus.write("Goal_Position", 1, round(ZERO + 1.3 / TICK))  # past the stop at 1.0 rad
        wait(bus, clock, 1.0)  # pressed into the stop at the torque limit
        t_stall = clock.now()
        assert bus.read("Status", 1) == 0 and bus.read("Present_Load", 1) == 700
        clock.sleep(600.0)  # hold the stall for 600 simulated seconds
        held_s = clock.now() - t_stall
        temperature = bus.read("Present_Temperature", 1)
        # the stall current is 0.7 × 2.7 A; the 1 s of approach adds less than 0.1 °C
        assert temperature == round(expected_c(0.7, held_s)) == 46
        assert bus.read("Present_Voltage", 1) == round(10 * (7.4 - R_OHM * 0.7 * STS.stall_current_a)) == 70
        bus.write("Torque_Enable", 1, 0)
        wait(bus, clock, 1.0)  # released from the stop, at rest again
        clock.sleep(3000.0)  # cools back to ambient
        assert (bus.read("Present_Temperature", 1), bus.read("Present_Voltage", 1)) == (25, 74)


def test_dynamixel_idle_stays_at_ambient_and_a_stall_warms_it() -> None:
    plant = JointPlant(params(), q0_rad=0.9)
    with rig("xl330-m288", plant, 0.9) as (_servo, clock, bus):
        assert isinstance(bus, DynamixelBus)
        wait(bus, clock, 0.5)  # at rest: the long sleep below is one step of the resting plant
        clock.sleep(600.0)  # idle, torque off
        assert (bus.read("Present_Temperature", 1), bus.read("Present_Input_Voltage", 1)) == (25, 50)
        bus.write("Operating_Mode", 1, 0)  # current control: the stall current is what is asked
        goal_ma = 1000
        bus.write("Goal_Current", 1, goal_ma)
        bus.write("Torque_Enable", 1, 1)
        wait(bus, clock, 1.0)  # pushed into the upper stop
        t_stall = clock.now()
        assert bus.read("Present_Current", 1) == goal_ma
        clock.sleep(600.0)
        fraction = goal_ma / 1000 / XL.stall_current_a
        assert bus.read("Present_Temperature", 1) == round(expected_c(fraction, clock.now() - t_stall)) == 45
        assert bus.read("Present_Input_Voltage", 1) == round(10 * (5.0 - R_OHM * goal_ma / 1000)) == 48
