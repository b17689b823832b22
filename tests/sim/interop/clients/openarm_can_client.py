"""Run in the PyPI ``openarm-can`` 1.4.1 environment: enactic's ``openarm_can.OpenArm`` on a SocketCAN interface.

It reads the arm as openarm_can's own examples do: the seven arm motors and the gripper registered with their
types and ids (0x01-0x08 / 0x11-0x18), every motor's PMAX (register 21) queried, one refresh, each position
read. Nothing is enabled or written. argv[1]: JSON ``{"interface": "vcan0"}``. Prints ``RESULT <json>``.
"""

import json
import sys

import openarm_can as oa

args = json.loads(sys.argv[1])
arm = oa.OpenArm(args["interface"], False)
types = [oa.MotorType.DM8009, oa.MotorType.DM8009, oa.MotorType.DM4340, oa.MotorType.DM4340,
         oa.MotorType.DM4310, oa.MotorType.DM4310, oa.MotorType.DM4310]
arm.init_arm_motors(types, list(range(0x01, 0x08)), list(range(0x11, 0x18)))
arm.init_gripper_motor(oa.MotorType.DM4310, 0x08, 0x18)
arm.set_callback_mode_all(oa.CallbackMode.PARAM)
arm.query_param_all(21)  # PMAX
arm.recv_all(100000)
motors = [*arm.get_arm().get_motors(), *arm.get_gripper().get_motors()]
result = {"pmax": [m.get_param(21) for m in motors]}
arm.set_callback_mode_all(oa.CallbackMode.STATE)
arm.refresh_all()
arm.recv_all(100000)
result["positions"] = [m.get_position() for m in motors]
result["enabled"] = [m.is_enabled() for m in motors]
print("RESULT " + json.dumps(result))
