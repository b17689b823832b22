"""Run in the PyPI ``damiao-motor`` 1.0.6 environment: its ``DaMiaoController`` over python-can's ``socketcand``.

The controller opens ``can.interface.Bus(channel=..., bustype=...)`` only; python-can takes the server's host and
port from the ``CAN_CONFIG`` environment variable. argv[1]: JSON ``{"channel": "can0", "esc": 5, "mst": 21,
"model": "4310", "target": 0.4}``. Prints ``RESULT <json>``.
"""

import json
import sys
import time

from damiao_motor import DaMiaoController

args = json.loads(sys.argv[1])
controller = DaMiaoController(channel=args["channel"], bustype="socketcand")
result = {}
try:
    motor = controller.add_motor(motor_id=args["esc"], feedback_id=args["mst"], motor_type=args["model"])
    result["registers"] = {rid: motor.get_register(rid, timeout=10.0) for rid in (21, 22, 23, 10, 9, 8, 7)}
    motor.ensure_control_mode("MIT")  # reads register 10: already MIT, nothing written
    motor.request_motor_feedback()  # 0x7FF refresh
    deadline = time.monotonic() + 30.0
    while not motor.get_states() and time.monotonic() < deadline:
        time.sleep(0.01)
    result["first"] = motor.get_states()
    # its MIT command enables a disabled motor itself (_check_motor_status) and is repeated as a control loop would
    while time.monotonic() < deadline:
        motor.send_cmd_mit(target_position=args["target"], stiffness=20.0, damping=0.5)
        time.sleep(0.02)
        state = motor.get_states()
        if state.get("status") == "ENABLED" and abs(state["pos"] - args["target"]) < 0.01:
            break
    result["moved"] = motor.get_states()
    motor.disable()
    time.sleep(0.2)
finally:
    controller.shutdown()
print("RESULT " + json.dumps(result))
