"""LeRobot 0.6.1's own ``DamiaoMotorsBus`` and ``OpenArmFollower``, unmodified, driving robocal's simulated OpenArm.

Each run is ``harness/damiao_harness.py`` in the interop environment (``make_env.py``), with the simulator in the
same process on python-can's ``virtual`` interface (``can_interface="virtual"``). What LeRobot reports is
compared with the simulator's truth: each motor's own reading (what the wire should carry) and the joint angle.
"""

from __future__ import annotations

import itertools
import json
import math
import os
import subprocess
import time
from pathlib import Path

import pytest

from robocal.backends.sim.control import SimControl

from .conftest import HARNESS, SimProcess, result_of

pytestmark = [pytest.mark.interop, pytest.mark.timeout(300)]

SRC = Path(__file__).resolve().parents[3] / "src"
STEP_DEG = math.degrees(25.0 / 65535)
"""One step of the 16-bit position field over ±12.5 rad (0.0219°): LeRobot reads the bottom of the step."""
TOL_DEG = STEP_DEG + math.degrees(math.tau / 16384)
"""A state-frame step plus one count of the simulated 14-bit output encoder."""
_channels = itertools.count()


def run_damiao(
    python: Path, cwd: Path, action: str, stdin: str = "", env: dict[str, str] | None = None, **args: object
) -> dict:
    args.setdefault("channel", f"lerobot-damiao-{os.getpid()}-{next(_channels)}")
    r = subprocess.run(
        [str(python), "-u", str(HARNESS / "damiao_harness.py"), action, json.dumps(args)],
        cwd=cwd,
        env=dict(os.environ, PYTHONPATH=f"{HARNESS}{os.pathsep}{SRC}", PYTHONNOUSERSITE="1", **(env or {})),
        input=stdin,
        capture_output=True,
        text=True,
        timeout=180,
    )
    assert r.returncode == 0, r.stdout[-2000:] + r.stderr[-3000:]
    return dict(result_of(r.stdout), stdout=r.stdout)


def test_lerobots_bus_enables_reads_zeros_moves_and_disables_the_simulated_arm(
    lerobot_python: Path, tmp_path: Path
) -> None:
    r = run_damiao(lerobot_python, tmp_path, "bus", zeroed=True, seed=2)
    names = ["joint_1", "joint_2", "joint_3", "joint_4", "joint_5", "joint_6", "joint_7", "gripper"]
    assert r["enabled_after_connect"] == dict.fromkeys(names, True)  # its handshake is the enable frame
    # LeRobot's handshake decodes the frame it sent (FF…FC), not the reply: until the first read every motor
    # "is" at +PMAX (716.2°), +VMAX, +TMAX, 255/252 °C (docs/damiao.md; the reference's known bug 3)
    gripper = r["cache_after_connect"]["gripper"]
    assert gripper == pytest.approx(
        {"position": math.degrees(12.5), "velocity": math.degrees(30.0), "torque": 10.0, "temp_mos": 255.0,
         "temp_rotor": 252.0}
    )  # fmt: skip
    assert r["cache_after_connect"]["joint_1"]["velocity"] == pytest.approx(math.degrees(45.0))
    for name in names:
        assert r["read_deg"][name] == pytest.approx(r["motor_deg"][name], abs=TOL_DEG), name
        assert r["motor_deg"][name] == pytest.approx(r["joint_deg"][name], abs=1e-9), name  # a zeroed arm
    assert r["joint_deg"]["joint_4"] == pytest.approx(2.0, abs=0.05)  # hanging: 2° off the elbow's stop
    # set_zero_position(): 0xFE into the motor's flash where the joint is (10°)
    assert r["zeroed"]["flash_writes"] == 1
    assert r["zeroed"]["read_deg"] == pytest.approx(-STEP_DEG / 2, abs=TOL_DEG)
    assert r["zeroed"]["zero_error_deg"] == pytest.approx(-10.0, abs=0.05)
    # sync_write("Goal_Position") with LeRobot's default kp 10 (9.89 after 12-bit packing): the joint follows
    moved = r["moved"]
    assert moved["last_kp"] == pytest.approx(81 * 500 / 4095)
    assert moved["motor_deg"] - moved["start_deg"] == pytest.approx(20.0, abs=0.5)
    assert moved["read_deg"] == pytest.approx(moved["motor_deg"], abs=TOL_DEG)
    assert r["enabled_after_disconnect"] == dict.fromkeys(names, False)


def test_openarm_follower_with_a_calibration_file_reads_the_joint_angles(
    lerobot_python: Path, tmp_path: Path
) -> None:
    cal_dir = tmp_path / "cal"
    cal_dir.mkdir()
    names = ["joint_1", "joint_2", "joint_3", "joint_4", "joint_5", "joint_6", "joint_7", "gripper"]
    entries = {
        n: {"id": i, "drive_mode": 0, "homing_offset": 0, "range_min": -90, "range_max": 90}
        for i, n in enumerate(names, start=1)
    }
    (cal_dir / "arm.json").write_text(json.dumps(entries, indent=4))
    r = run_damiao(lerobot_python, tmp_path, "follower", zeroed=True, seed=4, cal_dir=str(cal_dir), id="arm")
    assert r["flash_writes"] == dict.fromkeys(names, 0)  # a file: no prompt, no zeroing
    assert "Press ENTER" not in r["stdout"]
    for name in names:
        assert r["obs_deg"][name] == pytest.approx(r["joint_deg"][name], abs=TOL_DEG), name


def test_openarm_followers_own_calibration_zeros_the_pose_it_is_given(
    lerobot_python: Path, tmp_path: Path
) -> None:
    """LeRobot's procedure: "arm hanging straight down, gripper closed", ENTER, 0xFE to all eight motors.

    The simulated arm hangs with the elbow 2° off its stop and the gripper 2° open (a person's pose); LeRobot
    then reads 0 there, so its readings are off by exactly that pose: the gap docs/damiao.md reports.
    """
    cal_dir = tmp_path / "cal"
    r = run_damiao(lerobot_python, tmp_path, "follower", stdin="\n", seed=4, cal_dir=str(cal_dir), id="arm")
    assert "Arm hanging straight down" in r["stdout"]
    names = list(r["obs_deg"])
    assert r["flash_writes"] == dict.fromkeys(names, 1)
    for name in names:
        assert r["obs_deg"][name] == pytest.approx(-STEP_DEG / 2, abs=TOL_DEG), name
    error = {n: r["obs_deg"][n] - r["joint_deg"][n] for n in names}
    assert error["joint_4"] == pytest.approx(-2.0, abs=0.06)
    assert error["gripper"] == pytest.approx(2.0, abs=0.06)
    saved = json.loads(Path(r["path"]).read_text())
    assert {n: (c["range_min"], c["range_max"]) for n, c in saved.items()} == dict.fromkeys(names, (-90, 90))


def test_lerobots_bus_reaches_the_simulator_over_the_socketcand_loopback(
    lerobot_python: Path, tmp_path: Path
) -> None:
    """The transport another process reaches (``robocal sim openarm``'s): LeRobot opens ``socketcand``, and
    python-can takes the server's address from ``CAN_CONFIG`` (LeRobot passes only channel and bit rate)."""
    from robocal.backends.damiao.openarm import SimOpenArm
    from robocal.backends.sim.socketcand import SocketcandServer

    channel = f"lerobot-damiao-remote-{os.getpid()}"
    arm = SimOpenArm(channel, zeroed=True, seed=5, realtime=True)
    with arm, SocketcandServer({"can0": channel}) as server:
        config = json.dumps({"host": server.host, "port": server.port})
        r = run_damiao(
            lerobot_python, tmp_path, "remote", env={"CAN_CONFIG": config}, channel="can0", reads=10
        )
        deadline = (
            time.monotonic() + 30.0
        )  # the server may still be forwarding the last frames (a hang guard)
        while any(m.enabled for m in arm.motors.values()) and time.monotonic() < deadline:
            time.sleep(0.02)
        with arm.bus.lock:
            truth = {n: math.degrees(m.reading_rad(m.joint_rad())) for n, m in arm.motors.items()}
            enabled = {n: m.enabled for n, m in arm.motors.items()}
    assert set(r["read_deg"]) == set(truth)
    for name, deg in r["read_deg"].items():
        assert deg == pytest.approx(truth[name], abs=TOL_DEG), name
    assert enabled == dict.fromkeys(truth, False)  # disconnect() disabled them
    assert arm.motors["joint_1"].requests["enable"] == 1 and arm.motors["joint_1"].requests["refresh"] >= 1


@pytest.mark.slow
def test_openarm_follower_reads_robocal_sim_openarm_in_another_process(
    lerobot_python: Path, tmp_path: Path, sim_process: type[SimProcess]
) -> None:
    """``robocal sim openarm`` as the device, LeRobot's ``OpenArmFollower`` (with a calibration file) as the client
    over socketcand, the truth from the simulator's control socket: the path a calibration written by another
    process (robocal's) is checked on, since the motors' zeros live as long as the simulator."""
    sim = sim_process(["openarm", "--port", "0", "--zeroed", "--side", "left", "--seed", "2"])
    host, port = sim.info["socketcand"].rsplit(":", 1)
    cal_dir = tmp_path / "cal"
    cal_dir.mkdir()
    names = ["joint_1", "joint_2", "joint_3", "joint_4", "joint_5", "joint_6", "joint_7", "gripper"]
    entries = {
        n: {"id": i, "drive_mode": 0, "homing_offset": 0, "range_min": -90, "range_max": 90}
        for i, n in enumerate(names, start=1)
    }
    (cal_dir / "left.json").write_text(json.dumps(entries, indent=4))
    with SimControl(sim.info["control"]) as control:
        control.move("openarm_left_joint3", to=math.radians(30.0))
        truth = {state["motor"]: math.degrees(state["position"]) for state in control.state().values()}
    r = run_damiao(
        lerobot_python,
        tmp_path,
        "remote_follower",
        env={"CAN_CONFIG": json.dumps({"host": host, "port": int(port)})},
        channel="can1",
        cal_dir=str(cal_dir),
        id="left",
        side="left",
        reads=10,
    )
    assert set(r["obs_deg"]) == set(names)
    assert truth["joint_3"] == pytest.approx(30.0, abs=0.6)  # the hand let go; J3 carries no gravity
    for name in names:
        assert r["obs_deg"][name] == pytest.approx(truth[name], abs=TOL_DEG + 0.01), name
