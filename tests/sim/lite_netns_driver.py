"""``robocal sim lite`` in one process, ``robocal sweep`` against it from another.

Usage: ``python lite_netns_driver.py WORKDIR SEED [INTERFACE]``; prints the sweep report's homing offsets as one JSON
line. INTERFACE is udp_multicast (default: run it inside a private network namespace, so the multicast frames stay
on the namespace's loopback; the test sets up the namespace and its route) or socketcand (a socketcand server on
127.0.0.1, any free port; needs no namespace).
"""

from __future__ import annotations

import json
import signal
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

from conftest import Interactive, SimProcess
from robocal.backends.sim.control import SimControl
from robocal.backends.sim.lite import lite_urdf_text


def main() -> None:
    work, seed = Path(sys.argv[1]), sys.argv[2]
    interface = sys.argv[3] if len(sys.argv) > 3 else "udp_multicast"
    port = ["--port", "0"] if interface == "socketcand" else []
    (work / "lite.urdf").write_text(lite_urdf_text())
    sim = SimProcess(["lite", "--interface", interface, *port, "--seed", seed], work)
    try:
        source = sim.info["source"]
        sweep = Interactive(
            [
                sys.executable,
                "-m",
                "robocal",
                "sweep",
                "--urdf",
                "lite.urdf",
                "--source",
                source,
                "--out",
                "cal.yaml",
                "--report",
                "report.json",
            ],
            work,
        )
        with SimControl(sim.info["control"]) as ctl:
            deadline = time.monotonic() + 120  # a hang guard: starting can take long on a loaded machine
            while not all(j["last_write"].startswith("MIT") for j in ctl.state().values()):
                assert time.monotonic() < deadline, "the sweep never polled every motor"
                assert sweep.proc.poll() is None, sweep.text()
                time.sleep(0.1)
            # paced: each joint moves on only once the sweep read where it is (both stops seen, however loaded)
            ctl.sweep(seconds=3.0, dwell_s=0.3, paced=True)
        sweep.proc.send_signal(signal.SIGINT)  # first Ctrl-C: finish and write
        code, out = sweep.finish()
        report = json.loads((work / "report.json").read_text())
        offsets = {n: j["homing_offset"] for n, j in report["joints"].items()}
        print(json.dumps({"code": code, "source": source, "offsets": offsets, "output": out[-2000:]}))
    finally:
        code, err = sim.stop()
        assert code == 0, err


if __name__ == "__main__":
    main()
