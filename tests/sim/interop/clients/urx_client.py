"""Run in the python-urx 0.11 environment: ``urx.Robot`` (secondary 30002 and real-time 30003) at an address.

argv[1]: JSON ``{"host": …}``. Prints ``RESULT <json>``.
"""

import json
import sys
import time

import urx

host = json.loads(sys.argv[1])["host"]
rob = urx.Robot(host, use_rt=True)
try:
    result = {
        "running": rob.is_running(),
        "program_running": rob.is_program_running(),
        "getj": rob.getj(),
        "secondary_joints": rob.secmon.get_joint_data(wait=True),
        "robot_mode": rob.secmon.get_all_data(wait=True)["RobotModeData"],
    }
    t_end = time.monotonic() + 20.0  # hang guard: the real-time stream's first message
    rt = None
    while rt is None and time.monotonic() < t_end:
        rt = rob.rtmon.get_all_data(wait=True)
    result["rt_q_actual"] = list(map(float, rt["qActual"]))
    result["rt_tcp"] = list(map(float, rt["tcp"]))
    result["rt_ctrl_time"] = float(rt["ctrltimestamp"])
    try:  # the TCP pose through math3d: urx 0.11 calls PoseVector.tolist, which math3d 4 no longer has
        result["getl"] = list(map(float, rob.getl()))
    except AttributeError as exc:
        result["getl"] = f"AttributeError: {exc}"
finally:
    rob.close()
print("RESULT " + json.dumps(result, default=lambda x: x.tolist() if hasattr(x, "tolist") else str(x)))
