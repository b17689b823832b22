"""Run inside a private network namespace: ``robocal sim lite`` on udp_multicast, ``robocal sweep --auto`` against
it, SIGKILL of the sweep once a motor moves with its CAN timeout armed; prints the motor's state as one JSON line.

Usage: ``python watchdog_netns_driver.py WORKDIR``. The multicast frames stay on the namespace's loopback (the test
sets up the namespace and its route).
"""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

from conftest import CLIENT_ENV, SimProcess
from robocal.backends.sim.control import SimControl
from robocal.backends.sim.lite import lite_urdf_text

JOINT = "left_wrist_roll"


def main() -> None:
    work = Path(sys.argv[1])
    (work / "lite.urdf").write_text(lite_urdf_text())
    sim = SimProcess(["lite", "--interface", "udp_multicast", "--seed", "1"], work)
    try:
        proc = subprocess.Popen(
            [sys.executable, "-m", "robocal", "sweep", "--auto", "--urdf", "lite.urdf", "--robot", "bhl_arms",
             "--source", sim.info["source"], "--joints", JOINT, "--out", "cal.yaml", "--yes"],
            cwd=work, env=dict(os.environ, **CLIENT_ENV), stdin=subprocess.DEVNULL,
            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
        )
        with SimControl(sim.info["control"]) as ctl:
            deadline = time.monotonic() + 120  # a hang guard only
            while True:
                j = ctl.state()[JOINT]
                if j["enabled"] and j["can_timeout"] == 10000 and j["last_write"].startswith("MIT"):
                    break
                if j["watchdog_trips"] or proc.poll() is not None:  # robocal held up ≥ 0.5 s before the kill
                    break
                assert time.monotonic() < deadline, "the sweep never moved the joint"
                time.sleep(0.05)
            early = bool(j["watchdog_trips"])
            t_kill = time.monotonic()
            if proc.poll() is None:
                proc.send_signal(signal.SIGKILL)
            _, err = proc.communicate(timeout=60)
            deadline = time.monotonic() + 120
            while (j := ctl.state()[JOINT])["enabled"]:
                assert time.monotonic() < deadline, "the motor never stopped"
                time.sleep(0.05)
        print(json.dumps({"killed_by": proc.returncode, "t_kill": t_kill, "joint": j, "early": early, "err": err}))
    finally:
        code, err = sim.stop()
        assert code == 0, err


if __name__ == "__main__":
    main()
