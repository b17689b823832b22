"""``robocal sim <arm>`` as a standalone process: robocal's own commands in other processes, the operator
through the control socket, clean-up on Ctrl-C."""

from __future__ import annotations

import json
import os
import sys
from pathlib import Path

import pytest

from robocal.backends.feetech import FeetechBus
from robocal.backends.sim.control import SimControl
from robocal.errors import UsageError

from .conftest import Interactive, robocal

pytestmark = pytest.mark.timeout(120)


def calibrate_with_operator(cwd: Path, robot: str, port: str, control: str, robot_id: str) -> str:
    """``robocal lerobot calibrate`` in a child process; the operator holds the middle pose and sweeps."""
    run = Interactive(
        [
            sys.executable,
            "-m",
            "robocal",
            "lerobot",
            "calibrate",
            "--robot",
            robot,
            "--port",
            port,
            "--id",
            robot_id,
            "--calibration-dir",
            "cal",
        ],
        cwd,
    )
    code, out = run.calibrate_as_operator(control, "middle of its range of motion", "whole range of motion")
    assert code == 0, out
    return out


@pytest.mark.slow
def test_calibrate_then_check_in_two_processes_and_ctrl_c_cleans_up(sim_process, tmp_path: Path) -> None:
    sim = sim_process(["so101_follower", "--link", "so101.port"])
    link = tmp_path / "so101.port"
    assert os.readlink(link) == sim.info["port"]
    assert sim.info["control"] == str(tmp_path / "so101.port.control")
    out = calibrate_with_operator(tmp_path, "so101_follower", "./so101.port", sim.info["control"], "x")
    assert "calibration saved to cal/robots/so_follower/x.json" in out
    cal = json.loads((tmp_path / "cal/robots/so_follower/x.json").read_text())
    # the stock arm's gripper: stops 2000..3400 actual ticks, held at 2300 for "middle" → offset 2300 − 2047
    assert cal["gripper"] == {
        "id": 6,
        "drive_mode": 0,
        "homing_offset": 253,
        "range_min": 1747,
        "range_max": 3147,
    }
    with SimControl(sim.info["control"]) as ctl:
        state = ctl.state()
    assert state["gripper"]["Homing_Offset"] == 253
    assert state["gripper"]["last_write"] == "Lock=1"  # a finished calibration locks the EEPROM again, as it was
    check = robocal(
        "lerobot",
        "check",
        "--robot",
        "so101_follower",
        "--port",
        "./so101.port",
        "--id",
        "x",
        "--calibration-dir",
        "cal",
        cwd=tmp_path,
    )
    assert check.returncode == 0, check.stderr
    assert "EEPROM matches" in check.stdout
    code, err = sim.stop()
    assert code == 0, err
    assert "simulator stopped" in err
    assert not os.path.lexists(link)
    assert not os.path.lexists(tmp_path / "so101.port.control")


@pytest.mark.slow
def test_koch_follower_calibrates_on_the_standalone_dynamixel_arm(sim_process, tmp_path: Path) -> None:
    sim = sim_process(["koch_follower", "--seed", "3"])
    calibrate_with_operator(tmp_path, "koch_follower", sim.info["port"], sim.info["control"], "k")
    cal = json.loads((tmp_path / "cal/robots/koch_follower/k.json").read_text())
    assert [cal[n]["id"] for n in cal] == [1, 2, 3, 4, 5, 6]
    check = robocal(
        "lerobot",
        "check",
        "--robot",
        "koch_follower",
        "--port",
        sim.info["port"],
        "--id",
        "k",
        "--calibration-dir",
        "cal",
        cwd=tmp_path,
    )
    assert check.returncode == 0, check.stdout + check.stderr


@pytest.mark.slow
def test_operator_cannot_move_a_joint_whose_torque_is_on(sim_process) -> None:
    sim = sim_process(["so101_leader"])
    bus = FeetechBus(sim.info["port"], {6: "sts3215"})
    try:
        bus.write("Torque_Enable", 6, 1)
        with SimControl(sim.info["control"]) as ctl:
            with pytest.raises(UsageError, match="torque is on for gripper"):
                ctl.move("gripper", by=50)
            with pytest.raises(UsageError, match="torque is on for gripper"):
                ctl.sweep()
            assert ctl.move("shoulder_pan", by=-5000) == ctl.state()["shoulder_pan"]["low"]  # stop holds it
            assert ctl.state()["gripper"]["last_write"] == "Torque_Enable=1"
            bus.write("Torque_Enable", 6, 0)
            assert ctl.push("gripper", "min") == {"gripper": 1900.0}
    finally:
        bus.close()


def test_control_socket_refuses_bad_requests_with_a_message(sim_process) -> None:
    sim = sim_process(["koch_leader"])
    with SimControl(sim.info["control"]) as ctl:
        with pytest.raises(UsageError, match="unknown command 'fly'; commands: attach, mid, move, push"):
            ctl.request("fly")
        with pytest.raises(UsageError, match=r"unknown joint\(s\) elbow; joints: shoulder_pan"):
            ctl.move("elbow", to=1)
        with pytest.raises(UsageError, match="'to' must be a number"):
            ctl.request("move", joint="gripper", to="12")
        with pytest.raises(UsageError, match="exactly one of 'to' and 'by'"):
            ctl.request("move", joint="gripper")
        with pytest.raises(UsageError, match="stop must be 'min' or 'max'"):
            ctl.push("gripper", "middle")
        assert ctl.move("gripper", to=2500) == 2500.0  # the connection still works after refusals


@pytest.mark.slow
def test_link_over_a_regular_file_is_refused_and_the_file_kept(tmp_path: Path) -> None:
    keep = tmp_path / "port"
    keep.write_text("mine")
    r = robocal("sim", "so101_follower", "--link", str(keep), "--no-view", cwd=tmp_path, timeout=30)
    assert r.returncode == 2
    assert r.stderr.strip().splitlines() == [
        f"error: --link {keep}: exists and is not a symlink; choose another path"
    ]
    assert keep.read_text() == "mine"
    assert not (tmp_path / "port.control").exists()
