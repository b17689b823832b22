"""Simulated Feetech and Dynamixel servos with physics, driven by the unmodified SDKs through robocal's backends."""

from __future__ import annotations

import math
from collections.abc import Iterator
from contextlib import contextmanager

import pytest

from robocal.backends.dynamixel import DynamixelBus
from robocal.backends.feetech import FeetechBus
from robocal.backends.sim.physics import JointPlant, PlantParams, Scenario, SimClock, make_plant
from robocal.backends.sim.servo import SimServo, SimServoBus
from robocal.backends.sim.servo_firmware import RATINGS
from robocal.errors import CalibTimeoutError, DeviceError

pytestmark = pytest.mark.timeout(120)

TICK = 2 * math.pi / 4096
ZERO = 2048.0  # actual ticks at plant position 0
STS = RATINGS["sts3215"]
XL = RATINGS["xl330-m288"]


def params(**kw: float) -> PlantParams:
    base = {"stop_lower_rad": -1.0, "stop_upper_rad": 1.0, "stiffness_upper": 200.0, "stiction_nm": 0.05}
    base.update(kw)
    return PlantParams(**base)  # type: ignore[arg-type]


@contextmanager
def rig(
    model: str, plant: JointPlant, q0_rad: float = 0.0, packet_timeout_ms: float = 2000.0
) -> Iterator[tuple[SimServo, SimClock, object]]:
    """A simulated servo on a pty (its thread in this process) and a bus to it.

    The packet timeout is one the simulator's thread meets on a loaded machine (two tests at once on two cores and
    other work): a reply later than it is retried, and the retried read draws one more noise sample, so a run is
    then no longer the same as the one before. A test that expects lost replies passes a short one.
    """
    clock = SimClock()
    servo = SimServo(1, model, ZERO + q0_rad / TICK)
    servo.firmware = servo.kind.firmware(servo, plant, clock, zero_ticks=ZERO)
    cls = FeetechBus if servo.vendor == "feetech" else DynamixelBus
    with (
        SimServoBus([servo], clock=clock) as sim,
        cls(sim.port, {1: model}, packet_timeout_ms=packet_timeout_ms, retries=1) as bus,
    ):
        yield servo, clock, bus


def wait(bus: FeetechBus | DynamixelBus, clock: SimClock, seconds: float) -> int:
    """Poll Present_Position every 20 ms of simulated time; the last reading."""
    pos = 0
    for _ in range(round(seconds / 0.02)):
        pos = bus.sync_read("Present_Position", [1])[1]
        clock.sleep(0.02)
    return pos


def test_feetech_position_servo_pushes_the_stop_with_its_torque_limit() -> None:
    plant = JointPlant(params(), q0_rad=0.5)
    with rig("sts3215", plant, 0.5) as (_servo, clock, bus):
        assert isinstance(bus, FeetechBus)
        bus.write("Torque_Limit", 1, 300)  # 30 % of the stall torque
        bus.write("Torque_Enable", 1, 1)
        assert bus.read("Goal_Position", 1) == round(ZERO + 0.5 / TICK)  # torque on holds where it is
        bus.write("Goal_Position", 1, round(ZERO + 1.3 / TICK))  # past the stop at 1.0 rad
        pos = wait(bus, clock, 2.0)
        push = 0.3 * STS.stall_torque_nm
        # held in the stop at the torque limit: deflection push/k (± one tick, ± friction/k)
        assert (pos - ZERO) * TICK == pytest.approx(1.0 + push / 200.0, abs=TICK + 0.05 / 200)
        assert bus.read("Present_Load", 1) == 300
        assert bus.read("Present_Current", 1) == round(push / STS.kt_nm_a / 0.0065)
        assert bus.read("Moving", 1) == 0
        assert bus.read("Status", 1) == 0
        # a goal just past the stop: the P law and the stop spring share the lag (kp·lag below the limit)
        plant.params = params(stiction_nm=0.0, coulomb_nm=0.0)
        goal = round(ZERO + 1.0 / TICK) + 5
        bus.write("Goal_Position", 1, goal)
        wait(bus, clock, 1.0)
        kp = 32 / 1024 * STS.stall_torque_nm / TICK
        goal_rad = (goal - ZERO) * TICK
        q = (kp * goal_rad + 200.0 * 1.0) / (kp + 200.0)
        assert plant.q_rad == pytest.approx(q, abs=1e-6)
        assert bus.read("Present_Load", 1) == round(kp * (goal_rad - q) / STS.stall_torque_nm * 1000)


def test_feetech_stiction_no_motion_below_breakaway_and_goal_speed_ramp() -> None:
    plant = make_plant(Scenario(stiction_ratio=0.8), params(), search_torque_nm=1.0)
    with rig("sts3215", plant) as (_servo, clock, bus):
        assert isinstance(bus, FeetechBus)
        start = bus.read("Present_Position", 1)
        bus.write("Torque_Limit", 1, round(0.79 / STS.stall_torque_nm * 1000))  # 0.79 N·m < 0.8 breakaway
        bus.write("Torque_Enable", 1, 1)
        bus.write("Goal_Position", 1, start + 300)
        assert wait(bus, clock, 1.0) == start and bus.read("Moving", 1) == 0
        bus.write("Torque_Enable", 1, 0)
        bus.write("Torque_Limit", 1, 1000)
        bus.write("Goal_Velocity", 1, 200)  # ticks/s: 300 ticks take 1.5 s
        bus.write("Torque_Enable", 1, 1)
        bus.write("Goal_Position", 1, start + 300)
        wait(bus, clock, 0.5)
        mid = bus.read("Present_Position", 1)
        assert 50 < mid - start < 150 and bus.read("Moving", 1) == 1
        # it stops short of the goal by at most the stiction dead band breakaway/kp (13 ticks)
        kp = 32 / 1024 * STS.stall_torque_nm / TICK
        assert 0 <= start + 300 - wait(bus, clock, 2.0) <= 0.8 / kp / TICK + 1


def test_feetech_overload_latch_after_protection_time_and_torque_off_clears_it() -> None:
    plant = JointPlant(params(), q0_rad=0.9)
    with rig("sts3215", plant, 0.9) as (_servo, clock, bus):
        assert isinstance(bus, FeetechBus)
        bus.write("Overload_Torque", 1, 25)  # LeRobot's gripper setting
        bus.write("Protection_Time", 1, 50)  # 0.5 s
        bus.write("Protective_Torque", 1, 10)
        bus.write("Torque_Limit", 1, 300)
        bus.write("Torque_Enable", 1, 1)
        bus.write("Goal_Position", 1, round(ZERO + 1.3 / TICK))
        wait(bus, clock, 0.4)
        assert bus.read("Status", 1) == 0
        wait(bus, clock, 0.2)
        assert bus.sync_read("Status", [1])[1] == 0x20  # overload bit
        with pytest.raises(DeviceError, match=r"[Oo]verload"):  # every status packet carries it
            bus.read("Present_Load", 1)
        assert bus.sync_read("Present_Load", [1])[1] == 100  # limited to Protective_Torque 10 %
        bus.write("Torque_Enable", 1, 0)  # torque off clears the latch
        assert bus.read("Status", 1) == 0
        bus.write("Torque_Enable", 1, 1)
        bus.write("Goal_Position", 1, round(ZERO + 1.3 / TICK))
        wait(bus, clock, 0.2)
        assert bus.read("Present_Load", 1) == 300


def test_feetech_velocity_mode_and_silent_at_the_stop() -> None:
    plant = make_plant(Scenario(silent_at_stop=True), params(), search_torque_nm=0.6, q0_rad=0.8)
    with rig("sts3215", plant, 0.8, packet_timeout_ms=500.0) as (_servo, clock, bus):  # lost replies: short
        assert isinstance(bus, FeetechBus)
        bus.write("Operating_Mode", 1, 1)
        bus.write("Torque_Limit", 1, round(0.6 / STS.stall_torque_nm * 1000))
        bus.write("Torque_Enable", 1, 1)
        bus.write("Goal_Velocity", 1, 100)
        wait(bus, clock, 0.5)
        assert bus.read("Present_Velocity", 1) == pytest.approx(100, abs=3)
        with pytest.raises(CalibTimeoutError):
            wait(bus, clock, 3.0)  # pressed into the stop with 0.6 N·m: the replies are lost
        assert plant.q_rad > 1.0
        bus.sync_write("Torque_Enable", {1: 0})  # heard without a reply
        clock.sleep(0.1)
        assert bus.read("Torque_Enable", 1) == 0


def test_dynamixel_current_based_position_with_goal_current() -> None:
    plant = JointPlant(params(), q0_rad=0.5)
    with rig("xl330-m288", plant, 0.5) as (_servo, clock, bus):
        assert isinstance(bus, DynamixelBus)
        bus.write("Operating_Mode", 1, 5)
        bus.write("Goal_Current", 1, 400)  # mA
        bus.write("Torque_Enable", 1, 1)
        bus.write("Goal_Position", 1, round(ZERO + 1.3 / TICK))
        pos = wait(bus, clock, 3.0)
        push = 0.4 * XL.kt_nm_a
        assert (pos - ZERO) * TICK == pytest.approx(1.0 + push / 200.0, abs=TICK + 0.05 / 200)
        assert bus.read("Present_Current", 1) == 400
        assert bus.read("Hardware_Error_Status", 1) == 0
        with pytest.raises(DeviceError, match="not available to target address"):  # Access error
            bus.write("Operating_Mode", 1, 3)  # EEPROM locked while torque is on


def test_dynamixel_overload_shuts_torque_off_until_reboot() -> None:
    plant = JointPlant(params(), q0_rad=0.9)
    with rig("xl330-m288", plant, 0.9) as (_servo, clock, bus):
        assert isinstance(bus, DynamixelBus)
        assert bus.read("Position_P_Gain", 1) == 400  # the XL330's factory gain
        bus.write("Position_P_Gain", 1, 800)  # stiffer: the press into the stop saturates the output
        bus.write("Torque_Enable", 1, 1)  # position mode 3: full PWM
        bus.write("Goal_Position", 1, round(ZERO + 1.6 / TICK))
        wait(bus, clock, 0.9)
        assert bus.read("Hardware_Error_Status", 1) == 0
        wait(bus, clock, 0.3)
        with pytest.raises(DeviceError, match=r"[Hh]ardware error"):
            bus.read("Hardware_Error_Status", 1)
        assert bus.sync_read("Hardware_Error_Status", [1])[1] == 0x20
        assert bus.sync_read("Torque_Enable", [1])[1] == 0 and plant.tau_motor_nm == 0.0
        with pytest.raises(DeviceError):
            bus.write("Torque_Enable", 1, 1)
        bus.reboot(1)
        assert bus.read("Hardware_Error_Status", 1) == 0
        bus.write("Torque_Enable", 1, 1)
        assert bus.read("Torque_Enable", 1) == 1


def test_servo_runs_are_deterministic_with_a_seed() -> None:
    def run() -> list[int]:
        plant = make_plant(
            Scenario(asymmetric_stops=True), params(noise_rad=2 * TICK), search_torque_nm=0.5, seed=4
        )
        out = []
        with rig("sts3215", plant) as (_s, clock, bus):
            assert isinstance(bus, FeetechBus)
            bus.write("Torque_Limit", 1, 250)
            bus.write("Torque_Enable", 1, 1)
            bus.write("Goal_Position", 1, round(ZERO + 1.3 / TICK))
            for _ in range(60):
                out.append(bus.sync_read("Present_Position", [1])[1])
                clock.sleep(0.02)
        return out

    assert run() == run()


def test_so101_arm_with_physics_pushes_a_joint_into_its_truth_stop() -> None:
    from robocal.backends.sim.arm_physics import attach_physics
    from robocal.backends.sim.lerobot_arms import SimArm
    from robocal.workflows.lerobot import robot_spec

    clock = SimClock()
    spec = robot_spec("so101_follower")
    with SimArm(spec) as arm:
        plants = attach_physics(arm, clock, scenarios={"wrist_roll": Scenario(missing_stop="both")})
        assert plants["shoulder_pan"].params.stop_upper_rad == pytest.approx((3300 - 2100) * TICK)
        ids = {m.name: m.motor_id for m in spec.motors}
        with FeetechBus(arm.port, {m.motor_id: m.model for m in spec.motors}, packet_timeout_ms=500.0) as bus:
            pan = ids["shoulder_pan"]
            bus.write("Torque_Limit", pan, 250)
            bus.write("Torque_Enable", pan, 1)
            bus.write("Goal_Position", pan, 3600)
            for _ in range(100):
                pos = bus.sync_read("Present_Position", list(ids.values()))
                clock.sleep(0.02)
            push = 0.25 * STS.stall_torque_nm
            assert pos[pan] == pytest.approx(3300 + push / 300.0 / TICK, abs=1 + 0.06 / 300 / TICK)
            assert bus.read("Present_Load", pan) == 250
            assert pos[ids["elbow_flex"]] == 2000  # the others rest where they were
            roll = ids["wrist_roll"]  # no stops: the velocity mode turns it past the seam
            bus.write("Operating_Mode", roll, 1)
            bus.write("Torque_Enable", roll, 1)
            bus.write("Goal_Velocity", roll, 1000)
            clock.sleep(3.0)
            bus.sync_read("Present_Position", [roll])  # plants are integrated up to the clock at each packet
            # 1000 ticks/s for 3 s, past where the truth's stop (3981) would have held it
            assert plants["wrist_roll"].q_rad == pytest.approx(3000 * TICK, abs=0.05)


def test_koch_arm_current_based_gripper_and_no_current_mode_on_xl430() -> None:
    from robocal.backends.sim.arm_physics import attach_physics
    from robocal.backends.sim.lerobot_arms import SimArm
    from robocal.workflows.lerobot import robot_spec

    clock = SimClock()
    spec = robot_spec("koch_follower")
    models = {m.name: m.model for m in spec.motors}
    ids = {m.name: m.motor_id for m in spec.motors}
    with SimArm(spec) as arm:
        attach_physics(arm, clock)
        with DynamixelBus(
            arm.port, {m.motor_id: m.model for m in spec.motors}, packet_timeout_ms=500.0
        ) as bus:
            xl430 = next(n for n, m in models.items() if m == "xl430-w250")
            with pytest.raises(
                DeviceError, match="data value is out of range"
            ):  # no current sensing on the XL430
                bus.write("Operating_Mode", ids[xl430], 5)
            grip = ids["gripper"]
            assert models["gripper"].startswith("xl330")
            bus.write("Operating_Mode", grip, 5)
            bus.write("Goal_Current", grip, 300)
            bus.write("Torque_Enable", grip, 1)
            bus.write("Goal_Position", grip, 3500)  # past the truth's high stop (3000)
            for _ in range(100):
                pos = bus.sync_read("Present_Position", [grip])[grip]
                clock.sleep(0.02)
            push = 0.3 * XL.kt_nm_a
            assert pos == pytest.approx(3000 + push / 300.0 / TICK, abs=1 + 0.06 / 300 / TICK)
            assert bus.read("Present_Current", grip) == 300


def test_scenario_overload_latch_replaces_the_feetech_rule() -> None:
    plant = make_plant(Scenario(overload_latch=True), params(), search_torque_nm=0.5, q0_rad=0.9)
    with rig("sts3215", plant, 0.9) as (_servo, clock, bus):
        assert isinstance(bus, FeetechBus)
        bus.write("Torque_Limit", 1, round(0.5 / STS.stall_torque_nm * 1000))  # 26 %: under the 80 % default
        bus.write("Torque_Enable", 1, 1)
        bus.write("Goal_Position", 1, round(ZERO + 1.3 / TICK))
        wait(bus, clock, 0.05)
        assert bus.sync_read("Status", [1])[1] == 0
        wait(bus, clock, 0.4)  # past the 0.1 s at >= 90 % of the search torque
        assert bus.sync_read("Status", [1])[1] == 0x20
        assert bus.sync_read("Present_Load", [1])[1] == 0  # the scenario's latch cuts the torque
        bus.write("Torque_Enable", 1, 0)
        assert bus.read("Status", 1) == 0
