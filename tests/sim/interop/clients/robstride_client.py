"""Run in the PyPI ``robstride`` 0.1.0 environment: its ``Client`` over python-can's ``socketcand`` interface.

argv[1]: JSON ``{"host": …, "port": …, "channel": "can0", "motor": 11}``. Prints ``RESULT <json>``.
"""

import json
import sys

import can
from robstride.client import Client, RunMode

args = json.loads(sys.argv[1])
bus = can.Bus(interface="socketcand", channel=args["channel"], host=args["host"], port=args["port"])
try:
    client = Client(bus)  # host id 0xAA, the library's default; replies to another host id are refused
    motor = args["motor"]
    enabled = client.enable(motor)
    vbus = client.read_param(motor, "vbus")
    run_mode = client.read_param(motor, "run_mode")
    written = client.write_param(motor, "limit_torque", 3.5)
    limit = client.read_param(motor, "limit_torque")
    mechpos = client.read_param(motor, "mechpos")
    result = {
        "enabled": {"servo_id": enabled.servo_id, "mode": enabled.mode.name, "angle": enabled.angle},
        "vbus": vbus,
        "run_mode": run_mode.name if isinstance(run_mode, RunMode) else run_mode,
        "write_mode": written.mode.name,
        "limit_torque": limit,
        "mechpos": mechpos,
        "stray": str(bus.recv(timeout=0.3)),  # nothing left: no echo of its own requests
    }
finally:
    bus.shutdown()
print("RESULT " + json.dumps(result))
