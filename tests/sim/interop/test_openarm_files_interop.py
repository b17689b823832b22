"""LeRobot 0.6.1's own ``OpenArmFollower``, unmodified, reads the joint angles of an arm robocal calibrated.

robocal's session runs here (``sweep --auto --write-zero --format openarm-lerobot`` on ``sim:openarm``): it finds
both stops of every joint, stores each zero in its motor and writes LeRobot's file. The same simulated arm (same
seed: same motors), with those zeros in flash and powered up again, is then driven by LeRobot in the interop
environment (``harness/damiao_harness.py``, action ``follower`` with ``zeros``), which reads robocal's file.
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import pytest

from .test_damiao_interop import run_damiao

pytestmark = [pytest.mark.interop, pytest.mark.timeout(600)]


def test_the_same_seed_is_the_same_arm_so_copied_zeros_are_its_motors_after_a_power_cycle() -> None:
    from robocal.backends.damiao.openarm import SimOpenArm

    a, b = SimOpenArm("oa-seed-a", seed=7), SimOpenArm("oa-seed-b", seed=7)
    assert {n: m.mount_rad for n, m in a.motors.items()} == {n: m.mount_rad for n, m in b.motors.items()}
    a.motors["joint_3"].zero_abs_rad = (a.motors["joint_3"].mount_rad + 0.25) % math.tau  # a stored zero
    a.motors["joint_3"].power_on()
    b.motors["joint_3"].zero_abs_rad = a.motors["joint_3"].zero_abs_rad  # what the harness's "zeros" does
    b.motors["joint_3"].power_on()
    assert b.zero_error_rad("joint_3") == pytest.approx(a.zero_error_rad("joint_3"), abs=1e-12)
    assert b.zero_error_rad("joint_3") == pytest.approx(-0.25, abs=1e-9)


@pytest.mark.slow
def test_openarm_follower_reads_every_joint_within_0_1_deg_with_robocals_file_and_zeros(
    lerobot_python: Path, tmp_path: Path
) -> None:
    from tests.damiao.openarm_session import URDF, openarm_session

    from robocal.workflows.autocal.sweep import SweepAutoRequest

    seed = 7
    cal_dir = tmp_path / "cal"
    cal_dir.mkdir()
    request = SweepAutoRequest(URDF, f"sim:openarm?seed={seed}", cal_dir / "arm.json", robot="openarm_follower_right",
                               fmt="openarm-lerobot", write_zero=True)
    with openarm_session(request) as (_outcome, sim):  # the simulators are stopped before LeRobot's run
        zeros = {name: m.zero_abs_rad for name, m in sim.arm.motors.items()}
    written = json.loads((cal_dir / "arm.json").read_text())
    assert written["joint_4"]["range_min"] in (0, 1) and written["joint_1"]["range_max"] in (199, 200)
    r = run_damiao(lerobot_python, tmp_path, "follower", seed=seed, zeros=zeros, cal_dir=str(cal_dir), id="arm")
    assert "Press ENTER" not in r["stdout"] and all(v == 0 for v in r["flash_writes"].values())
    errors = {n: r["obs_deg"][n] - r["joint_deg"][n] for n in zeros}
    assert max(abs(e) for e in errors.values()) < 0.1, errors
    assert all(math.isfinite(e) for e in errors.values())
