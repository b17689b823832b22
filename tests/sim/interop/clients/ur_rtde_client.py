"""Run in the ur_rtde 1.6.5 environment: RTDEReceiveInterface and DashboardClient against a controller's address.

argv[1]: JSON ``{"host": …}`` (ur_rtde uses the standard ports 30004 and 29999). Prints ``RESULT <json>``.
"""

import json
import sys
import time

import dashboard_client
import rtde_receive

host = json.loads(sys.argv[1])["host"]


def wait_mode(r, mode, limit_s=20.0):
    """The robot mode RTDE reports, once it is ``mode`` or after ``limit_s`` (a hang guard)."""
    end = time.monotonic() + limit_s
    while r.getRobotMode() != mode and time.monotonic() < end:
        time.sleep(0.01)
    return r.getRobotMode()


r = rtde_receive.RTDEReceiveInterface(host)
samples = []
for _ in range(3):
    samples.append(
        {"t": r.getTimestamp(), "q": r.getActualQ(), "target_q": r.getTargetQ(), "tcp": r.getActualTCPPose()}
    )
    time.sleep(0.05)
result = {
    "connected": r.isConnected(),
    "samples": samples,
    "robot_mode": r.getRobotMode(),
    "safety_mode": r.getSafetyMode(),
    "runtime_state": r.getRuntimeState(),
    "speed_scaling": r.getSpeedScaling(),
    "payload": r.getPayload(),
}
d = dashboard_client.DashboardClient(host)
d.connect()
result["dashboard"] = {
    "connected": d.isConnected(),
    "robotmode": d.robotmode(),
    "polyscope": d.polyscopeVersion(),
    "serial": d.getSerialNumber(),
    "safetystatus": d.safetystatus(),
    "program_state": d.programState(),
    "remote": d.isInRemoteControl(),
}
d.powerOff()
result["after_power_off"] = {"dashboard": d.robotmode(), "rtde": wait_mode(r, 3)}
d.powerOn()
result["after_power_on"] = {"dashboard": d.robotmode(), "rtde": wait_mode(r, 5)}
d.brakeRelease()
result["after_brake_release"] = {"dashboard": d.robotmode(), "rtde": wait_mode(r, 7)}
d.disconnect()
r.disconnect()
print("RESULT " + json.dumps(result))
