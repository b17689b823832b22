"""Run inside a private network namespace: ``robocal sim lite`` (joint physics in real time) on udp_multicast and
``robocal sweep --auto`` against it in another process; prints the outcome and the simulator's state as one JSON line.

Usage: ``python lite_physics_netns_driver.py WORKDIR JOINT``.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

from conftest import CLIENT_ENV, SimProcess
from robocal.backends.sim.control import SimControl
from robocal.backends.sim.lite import lite_urdf_text


def main() -> None:
    work, joint = Path(sys.argv[1]), sys.argv[2]
    (work / "lite.urdf").write_text(lite_urdf_text())
    sim = SimProcess(["lite", "--interface", "udp_multicast", "--seed", "3"], work)
    try:
        with SimControl(sim.info["control"]) as ctl:
            before = ctl.state()[joint]
        r = subprocess.run(
            [sys.executable, "-m", "robocal", "sweep", "--auto", "--urdf", "lite.urdf", "--robot", "bhl_arms",
             "--source", sim.info["source"], "--joints", joint, "--out", "cal.yaml", "--report", "report.json",
             "--yes"],
            cwd=work, env=dict(os.environ, **CLIENT_ENV), stdin=subprocess.DEVNULL, capture_output=True, text=True,
            timeout=400,
        )  # fmt: skip
        with SimControl(sim.info["control"]) as ctl:
            after = ctl.state()[joint]
        report = json.loads((work / "report.json").read_text()) if (work / "report.json").exists() else None
        print(json.dumps({"code": r.returncode, "err": r.stderr, "before": before, "after": after, "report": report}))
    finally:
        code, err = sim.stop()
        assert code == 0, err


if __name__ == "__main__":
    main()
