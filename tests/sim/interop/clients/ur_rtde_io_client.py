"""Run in the ur_rtde 1.6.5 environment: RTDEIOInterface sets outputs, registers and the speed slider; the
receive interface reads back what the controller then reports.

argv[1]: JSON ``{"host": …}``. Prints ``RESULT <json>``.
"""

import json
import sys
import time

import rtde_io
import rtde_receive

host = json.loads(sys.argv[1])["host"]
io = rtde_io.RTDEIOInterface(host)
result = {
    "set": [
        io.setStandardDigitalOut(2, True),
        io.setToolDigitalOut(1, True),
        io.setInputIntRegister(18, 42),
        io.setInputDoubleRegister(19, 1.5),
        io.setSpeedSlider(0.5),
        io.setAnalogOutputVoltage(1, 0.25),
    ]
}
r = rtde_receive.RTDEReceiveInterface(host)
end = time.monotonic() + 20.0  # hang guard: the first data package after the inputs
while r.getTargetSpeedFraction() != 0.5 and time.monotonic() < end:
    time.sleep(0.01)
result["digital_output_bits"] = r.getActualDigitalOutputBits()
result["digital_out_2"] = r.getDigitalOutState(2)
result["speed_fraction"] = r.getTargetSpeedFraction()
result["analog_output_1"] = r.getStandardAnalogOutput1()
r.disconnect()
io.disconnect()
print("RESULT " + json.dumps(result))
