"""Run in the st3215 0.4.2 environment (PyPI ``st3215``): its ``ST3215`` class on a port.

argv[1]: JSON ``{"port": …, "ids": [1, …], "middle": 3}``. Prints ``RESULT <json>``.
"""

import json
import sys

from st3215 import ST3215

args = json.loads(sys.argv[1])
servo = ST3215(args["port"])
result = {"ping": {}, "read": {}}
for i in args["ids"]:
    result["ping"][i] = servo.PingServo(i)
    result["read"][i] = {
        "position": servo.ReadPosition(i),
        "voltage": servo.ReadVoltage(i),
        "temperature": servo.ReadTemperature(i),
        "mode": servo.ReadMode(i),
        "correction": servo.ReadCorrection(i),
        "moving": servo.IsMoving(i),
    }
middle = args["middle"]
result["define_middle"] = servo.DefineMiddle(middle)  # Torque_Enable = 128: the present position becomes 2048
result["after_middle"] = {"position": servo.ReadPosition(middle), "correction": servo.ReadCorrection(middle)}
result["ping_absent"] = servo.PingServo(max(args["ids"]) + 1)
print("RESULT " + json.dumps(result))
