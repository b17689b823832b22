"""Runs LeRobot 0.6.1's own code (in the interop virtual environment) for robocal's interop tests.

Usage: ``python -u lerobot_harness.py ACTION JSON_ARGS``. Prompts of LeRobot's ``input()`` come on standard
output and are answered on standard input (the test plays the person); results are printed as one line
``RESULT <json>`` at the end.
"""

import json
import pathlib
import sys

import interop_stubs  # noqa: F401  (must come first: stand-ins for torch & co.)

SIM_FLOOR_MS = 500.0
"""Least wait for a status packet. Real servos answer within microseconds; the simulator is a Python process
sharing the machine's cores with the test suite (and, on a developer's machine, with other suites), so the
SDKs' 34-50 ms waits are raised. Only the waiting changes: every packet is still LeRobot's."""


def _patch_timeouts():
    import dynamixel_sdk
    import lerobot.motors.feetech.feetech as lerobot_feetech

    original_feetech = lerobot_feetech.patch_setPacketTimeout

    def feetech_timeout(self, packet_length):
        original_feetech(self, packet_length)
        self.packet_timeout = max(self.packet_timeout, SIM_FLOOR_MS)

    lerobot_feetech.patch_setPacketTimeout = feetech_timeout
    original_dxl = dynamixel_sdk.PortHandler.setPacketTimeout

    def dxl_timeout(self, packet_length):
        original_dxl(self, packet_length)
        self.packet_timeout = max(self.packet_timeout, SIM_FLOOR_MS)

    dynamixel_sdk.PortHandler.setPacketTimeout = dxl_timeout


def make_robot(a):
    cal_dir = pathlib.Path(a["cal_dir"])
    if a["robot"] == "so101_follower":
        from lerobot.robots.so_follower import SO101Follower, SOFollowerRobotConfig

        return SO101Follower(SOFollowerRobotConfig(port=a["port"], id=a["id"], calibration_dir=cal_dir))
    if a["robot"] == "koch_follower":
        from lerobot.robots.koch_follower import KochFollower, KochFollowerConfig

        return KochFollower(KochFollowerConfig(port=a["port"], id=a["id"], calibration_dir=cal_dir))
    raise SystemExit(f"unknown robot {a['robot']}")


def cal_dict(cal):
    return {name: vars(c) for name, c in cal.items()}


def main():
    action, a = sys.argv[1], json.loads(sys.argv[2])
    _patch_timeouts()
    result = {}
    if action == "calibrate":  # what lerobot-calibrate does
        robot = make_robot(a)
        robot.connect(calibrate=False)
        robot.calibrate()
        robot.disconnect()
        result = {"path": str(robot.calibration_fpath)}
    elif action == "load":  # draccus reads the file when the robot is made
        robot = make_robot(a)
        result = {"calibration": cal_dict(robot.calibration)}
    elif action == "connect":  # connect() checks the motors against the file (no calibration prompt)
        robot = make_robot(a)
        robot.bus.connect()
        result = {"is_calibrated": robot.is_calibrated, "motors": cal_dict(robot.bus.read_calibration())}
        robot.bus.disconnect()
    elif action == "write_limit":  # change one limit with LeRobot's bus
        robot = make_robot(a)
        robot.bus.connect()
        robot.bus.disable_torque(a["motor"])
        robot.bus.write(a["register"], a["motor"], a["value"], normalize=False)
        robot.bus.disconnect()
    elif action == "normalize":  # LeRobot's normalisation: live reads and a grid of raw values
        robot = make_robot(a)
        bus = robot.bus
        bus.connect()
        bus.calibration = robot.calibration
        raw = bus.sync_read("Present_Position", normalize=False)
        norm = bus.sync_read("Present_Position")
        grid = {}
        for name, motor in bus.motors.items():
            grid[name] = [bus._normalize({motor.id: v})[motor.id].hex() for v in a["grid"]]
        bus.disconnect()
        result = {"raw": raw, "norm": {k: float(v).hex() for k, v in norm.items()}, "grid": grid}
    elif action == "broadcast_ping":
        from lerobot.motors.dynamixel import DynamixelMotorsBus
        from lerobot.motors.feetech import FeetechMotorsBus

        cls = FeetechMotorsBus if a["vendor"] == "feetech" else DynamixelMotorsBus
        bus = cls(a["port"], {})
        bus._connect(handshake=False)
        bus.set_baudrate(a.get("baudrate", 1_000_000))
        found = bus.broadcast_ping()
        bus.port_handler.closePort()
        result = {"found": found}
        if a.get("scan"):
            result["scan"] = {str(k): v for k, v in cls.scan_port(a["port"]).items()}
    elif action == "setup_motors":  # what lerobot-setup-motors does
        robot = make_robot(a)
        robot.setup_motors()
        result = {"ids": {n: m.id for n, m in robot.bus.motors.items()}}
    else:
        raise SystemExit(f"unknown action {action}")
    print("RESULT " + json.dumps(result), flush=True)


if __name__ == "__main__":
    main()
