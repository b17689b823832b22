"""Run in the dynamixel-sdk 4.1.0 environment: ping, reads, Bulk Read, Fast Sync Read, Fast Bulk Read on a port.

argv[1]: JSON ``{"port": …, "baudrate": 1000000, "ids": [1, …]}``. Prints ``RESULT <json>``. A transaction whose
answer came late (a loaded machine holds the simulator up past the SDK's ~34 ms timeout) is tried again, up to 5
times, as an application on a noisy bus would; ``retries`` counts them.
"""

import json
import sys

from dynamixel_sdk import COMM_SUCCESS, GroupBulkRead, GroupSyncRead, PacketHandler, PortHandler

args = json.loads(sys.argv[1])
ids = args["ids"]
port = PortHandler(args["port"])
assert port.openPort() and port.setBaudRate(args["baudrate"])
packet = PacketHandler(2.0)
retries = 0


def tries(call):
    """``call()`` returns (..., comm, error) or comm; again while comm is not COMM_SUCCESS (5 tries)."""
    global retries
    for _ in range(5):
        out = call()
        comm = out if isinstance(out, int) else out[-2]
        if comm == COMM_SUCCESS:
            return out
        retries += 1
    raise RuntimeError(f"{call}: {packet.getTxRxResult(comm)}")


result = {"models": {}, "eeprom": {}}
for i in ids:
    model, _, error = tries(lambda i=i: packet.ping(port, i))
    result["models"][i] = [model, error]
    result["eeprom"][i] = {
        "Status_Return_Level": tries(lambda i=i: packet.read1ByteTxRx(port, i, 68))[0],
        "PWM_Limit": tries(lambda i=i: packet.read2ByteTxRx(port, i, 36))[0],
        "Current_Limit": tries(lambda i=i: packet.read2ByteTxRx(port, i, 38))[0],
        "Present_Position": tries(lambda i=i: packet.read4ByteTxRx(port, i, 132))[0],
    }

bulk = GroupBulkRead(port, packet)
layout = {ids[0]: (132, 4), ids[1]: (0, 2), ids[2]: (68, 1)}  # different items per servo
for i, (address, length) in layout.items():
    assert bulk.addParam(i, address, length)
tries(bulk.txRxPacket)
result["bulk"] = {i: bulk.getData(i, a, n) for i, (a, n) in layout.items()}
tries(bulk.fastBulkRead)
result["fast_bulk"] = {i: bulk.getData(i, a, n) for i, (a, n) in layout.items()}

sync = GroupSyncRead(port, packet, 132, 4)
for i in ids:
    assert sync.addParam(i)
tries(sync.fastSyncRead)
result["fast_sync"] = {i: sync.getData(i, 132, 4) for i in ids}
tries(sync.txRxPacket)
result["sync"] = {i: sync.getData(i, 132, 4) for i in ids}
result["retries"] = retries
port.closePort()
print("RESULT " + json.dumps(result))
