"""LeRobot 0.6.1's own Damiao code (``DamiaoMotorsBus``, ``OpenArmFollower``) against robocal's simulated OpenArm.

Usage: ``python -u damiao_harness.py ACTION JSON_ARGS`` in the interop environment, with robocal's ``src`` on
``PYTHONPATH``. The simulator runs in this process on python-can's ``virtual`` interface (LeRobot is given
``can_interface="virtual"``, a value its config passes straight to ``can.Bus``); LeRobot's code is unmodified.
LeRobot waits only 1-10 ms for each reply and keeps its last value when one is late, so every read is repeated
(:data:`READS`) on an arm that does not move meanwhile: the last value is the newest reply. Results are printed as
one line ``RESULT <json>``; ``input()`` prompts come on standard output and are answered on standard input.
"""

import json
import math
import pathlib
import sys

import interop_stubs  # noqa: F401  (must come first: stand-ins for torch & co.)

READS = 5
"""Reads per observation (the arm is still; the newest of them is kept by LeRobot's cache)."""


def _arm(a):
    from robocal.backends.damiao.openarm import SimOpenArm

    arm = SimOpenArm(
        a["channel"], side=a.get("side", "right"), seed=a.get("seed", 0), zeroed=a.get("zeroed", False)
    )
    # "zeros": the zeros another session stored in the motors' flash (motor name -> absolute angle, rad): the same
    # seed is the same arm, so these are that arm's motors after a power cycle
    for name, zero_abs_rad in a.get("zeros", {}).items():
        arm.motors[name].zero_abs_rad = zero_abs_rad % math.tau
        arm.motors[name].power_on()
    return arm


def _truth(arm):
    """Joint angles (deg) and each motor's own reading (deg, what a motor should report) from the simulator."""
    arm.bus.settle()  # every frame LeRobot sent so far has been handled
    with arm.bus.lock:
        joints = {n: math.degrees(p.link_rad) for n, p in arm.plants.items()}
        motors = {n: math.degrees(m.reading_rad(m.joint_rad())) for n, m in arm.motors.items()}
    return joints, motors


def _motors():
    from lerobot.motors import Motor, MotorNormMode
    from lerobot.robots.openarm_follower.config_openarm_follower import OpenArmFollowerConfigBase

    config = OpenArmFollowerConfigBase(port="unused")
    motors = {}
    for name, (send_id, recv_id, kind) in config.motor_config.items():
        motor = Motor(send_id, kind, MotorNormMode.DEGREES)
        motor.recv_id = recv_id
        motor.motor_type_str = kind
        motors[name] = motor
    return motors


def bus_action(a):
    """DamiaoMotorsBus: connect (enable handshake), read, set zero on one joint, move one joint, disable."""
    from lerobot.motors.damiao import DamiaoMotorsBus

    result = {}
    with _arm(a) as arm:
        bus = DamiaoMotorsBus(port=a["channel"], motors=_motors(), can_interface="virtual", use_can_fd=True)
        bus.connect()
        result["cache_after_connect"] = {n: dict(v) for n, v in bus._last_known_states.items()}
        arm.bus.settle()
        result["enabled_after_connect"] = {n: m.enabled for n, m in arm.motors.items()}
        for _ in range(READS):
            positions = bus.sync_read("Present_Position")
        result["read_deg"] = {n: float(v) for n, v in positions.items()}
        result["joint_deg"], result["motor_deg"] = _truth(arm)
        # set zero on joint_6, held 10 degrees off its hanging pose
        arm.set_joint("joint_6", math.radians(10.0))
        bus.disable_torque("joint_6")
        bus.set_zero_position("joint_6")
        for _ in range(READS):
            after = bus.sync_read("Present_Position")
        result["zeroed"] = {
            "read_deg": float(after["joint_6"]),
            "flash_writes": arm.motors["joint_6"].flash_writes,
            "zero_error_deg": math.degrees(arm.zero_error_rad("joint_6")),
        }
        # move joint_5 with LeRobot's MIT write (kp 10, kd 0.5 by default), one simulated second
        bus.enable_torque("joint_5")
        start = float(bus.sync_read("Present_Position")["joint_5"])
        bus.sync_write("Goal_Position", {"joint_5": start + 20.0})
        arm.clock.sleep(1.0)
        for _ in range(READS):
            moved = bus.sync_read("Present_Position")
        result["moved"] = {
            "start_deg": start,
            "read_deg": float(moved["joint_5"]),
            "motor_deg": _truth(arm)[1]["joint_5"],
            "last_kp": arm.motors["joint_5"].last_command.kp,
        }
        bus.disconnect(disable_torque=True)
        arm.bus.settle()
        result["enabled_after_disconnect"] = {n: m.enabled for n, m in arm.motors.items()}
    return result


def remote_action(a):
    """DamiaoMotorsBus on python-can's socketcand interface (host and port from ``CAN_CONFIG``): connect, read."""
    from lerobot.motors.damiao import DamiaoMotorsBus

    bus = DamiaoMotorsBus(port=a["channel"], motors=_motors(), can_interface="socketcand", use_can_fd=True)
    bus.connect()
    for _ in range(a.get("reads", READS)):
        positions = bus.sync_read("Present_Position")
    bus.disconnect(disable_torque=True)
    return {"read_deg": {n: float(v) for n, v in positions.items()}}


def remote_follower_action(a):
    """OpenArmFollower on python-can's socketcand interface (``robocal sim openarm``; address from ``CAN_CONFIG``):
    connect with the calibration file in ``cal_dir`` (or LeRobot's own procedure without one), observe, disconnect."""
    from lerobot.robots.openarm_follower import OpenArmFollower, OpenArmFollowerConfig

    config = OpenArmFollowerConfig(
        port=a["channel"],
        id=a["id"],
        calibration_dir=pathlib.Path(a["cal_dir"]),
        can_interface="socketcand",
        side=a.get("side"),
    )
    robot = OpenArmFollower(config)
    robot.connect()
    for _ in range(a.get("reads", READS)):
        obs = robot.get_observation()
    robot.disconnect()
    return {"obs_deg": {k[: -len(".pos")]: float(v) for k, v in obs.items() if k.endswith(".pos")}}


def follower_action(a):
    """OpenArmFollower: connect (calibrating with LeRobot's own procedure when no file is there), observe."""
    from lerobot.robots.openarm_follower import OpenArmFollower, OpenArmFollowerConfig

    cal_dir = pathlib.Path(a["cal_dir"])
    with _arm(a) as arm:
        config = OpenArmFollowerConfig(
            port=a["channel"],
            id=a["id"],
            calibration_dir=cal_dir,
            can_interface="virtual",
            side=a.get("side"),
        )
        robot = OpenArmFollower(config)
        robot.connect()  # no file: LeRobot's calibrate() asks for ENTER, zeros every motor where the arm is
        arm.bus.settle()
        for _ in range(READS):
            obs = robot.get_observation()
        joints, motors = _truth(arm)
        result = {
            "obs_deg": {k[: -len(".pos")]: float(v) for k, v in obs.items() if k.endswith(".pos")},
            "joint_deg": joints,
            "motor_deg": motors,
            "flash_writes": {n: m.flash_writes for n, m in arm.motors.items()},
            "path": str(robot.calibration_fpath),
        }
        robot.disconnect()
    return result


def main():
    action, a = sys.argv[1], json.loads(sys.argv[2])
    sys.setswitchinterval(0.0005)  # LeRobot waits 1 ms for a reply; let the simulator's thread answer in time
    actions = {
        "bus": bus_action,
        "follower": follower_action,
        "remote": remote_action,
        "remote_follower": remote_follower_action,
    }
    if action not in actions:
        raise SystemExit(f"unknown action {action}")
    print("RESULT " + json.dumps(actions[action](a)), flush=True)


if __name__ == "__main__":
    main()
