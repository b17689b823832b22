"""SIGKILL of robocal during a motion: the simulated motors stop themselves within their watchdog time (issue 26).

robocal arms each moving motor's host-loss watchdog before its first motion (Dynamixel ``Bus_Watchdog`` 0.5 s,
Robstride ``canTimeout`` 0.5 s). A killed process cannot make anything limp; the simulators (``robocal sim``, in
their own process, on the monotonic clock every process shares) model the watchdogs as the manuals describe them,
so the oracle is the simulator's own state: the watchdog fired exactly 0.5 s after the last packet it heard, the
motor stopped (Dynamixel: the goal is where the joint is, goals refused; Robstride: reset mode), and the last packet
came no later than the kill (give or take the packets already on their way).
"""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import pytest

from robocal.backends.sim.control import SimControl

from .conftest import CLIENT_ENV
from .test_sim_lite_cli import NETNS_SETUP, _netns_available

pytestmark = pytest.mark.timeout(300)

IN_FLIGHT_S = 1.0
"""Packets written before the kill may reach a loaded simulator a little later (a generous bound)."""


def _poll(what: str, ready: Callable[[], Any], proc: subprocess.Popen[str] | None = None) -> Any:
    deadline = time.monotonic() + 120  # a hang guard only
    while True:
        got = ready()
        if got:
            return got
        if proc is not None and proc.poll() is not None:
            raise AssertionError(f"robocal ended before {what}: {proc.communicate()}")
        assert time.monotonic() < deadline, f"no {what} within 120 s"
        time.sleep(0.05)


@pytest.mark.slow
def test_sigkill_during_lerobot_auto_the_dynamixel_bus_watchdog_stops_the_servo(sim_process: Any, tmp_path: Path) -> None:
    sim = sim_process(["koch_follower"])
    proc = subprocess.Popen(
        [sys.executable, "-m", "robocal", "lerobot", "calibrate", "--auto", "--robot", "koch_follower",
         "--port", sim.info["port"], "--id", "k", "--calibration-dir", "cal", "--joints", "gripper", "--yes"],
        cwd=tmp_path, env=dict(os.environ, **CLIENT_ENV), stdin=subprocess.DEVNULL,
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
    )
    with SimControl(sim.info["control"]) as ctl:
        def moving() -> bool:
            g = ctl.state()["gripper"]
            armed = g["torque"] and g["Bus_Watchdog"] == 25 and g["last_write"].startswith("Goal_Position")
            return bool(armed or g["Bus_Watchdog"] == -1)  # -1: a loaded machine held robocal up ≥ 0.5 s

        _poll("a motion with the watchdog armed", moving, proc)
        t_kill = time.monotonic()
        proc.send_signal(signal.SIGKILL)
        proc.communicate(timeout=60)
        assert proc.returncode == -signal.SIGKILL
        g = _poll("the watchdog", lambda: (s := ctl.state()["gripper"])["Bus_Watchdog"] == -1 and s)
    (last, at), = g["watchdog_trips"]
    assert at - last == pytest.approx(0.5, abs=1e-9)
    assert last <= t_kill + IN_FLIGHT_S
    assert g["Goal_Position"] == round(g["reading"])  # stopped where it is; torque stays on, goals refused
    assert g["torque"] is True
    assert not (tmp_path / "cal").exists()  # killed before the end: no calibration file


@pytest.mark.slow
def test_sigkill_during_sweep_auto_the_robstride_can_timeout_stops_the_motor(tmp_path: Path) -> None:
    reason = _netns_available()
    if reason:
        pytest.skip(reason)
    pytest.importorskip("msgpack", reason="python-can's udp_multicast needs msgpack")
    driver = Path(__file__).with_name("watchdog_netns_driver.py")
    r = subprocess.run(
        ["unshare", "--net", "sh", "-c", f'{NETNS_SETUP} && exec "$0" "$@"', sys.executable, str(driver),
         str(tmp_path)],
        capture_output=True, text=True, timeout=250,
    )
    assert r.returncode == 0, r.stderr[-3000:]
    out = json.loads(r.stdout.strip().splitlines()[-1])
    joint = out["joint"]
    (last, at), = joint["watchdog_trips"]
    assert at - last == pytest.approx(0.5, abs=1e-9)
    assert joint["enabled"] is False and joint["torque"] is False  # reset mode: limp
    if out["early"]:  # the loaded machine held robocal up ≥ 0.5 s before the kill: the watchdog already acted
        assert out["killed_by"] in (-signal.SIGKILL, 3), out
        return
    assert out["killed_by"] == -signal.SIGKILL
    assert last <= out["t_kill"] + IN_FLIGHT_S
    assert joint["can_timeout"] == 10000  # still armed (nobody disarmed it): 0.5 s


@pytest.mark.timeout(120)
def test_without_a_simulated_clock_the_watchdogs_run_on_the_monotonic_clock() -> None:
    """What the ``robocal sim`` processes above rely on: the bus threads fire the watchdogs of a silent host."""
    pytest.importorskip("can")
    from robocal.backends.robstride.sim import SimMotor, SimMotorBus
    from robocal.backends.sim.lerobot_arms import SimArm
    from robocal.workflows.lerobot import robot_spec

    motor = SimMotor(can_id=5, model="rs-05", can_timeout=400)  # 400 = 20 ms
    with SimArm(robot_spec("koch_follower")) as arm, SimMotorBus(f"robocal-wd-{os.getpid()}", [motor]) as can_bus:
        servo = arm.servo("gripper")
        with arm.bus.lock, can_bus.lock:
            servo.set_reg("Torque_Enable", 1)
            servo.set_reg("Bus_Watchdog", 1)  # 20 ms
            motor.mode = 2  # enabled (run mode)
            servo.watchdog_rx_s = motor.last_rx_s = time.monotonic()
        _poll("both trips", lambda: servo.watchdog_trips and motor.watchdog_trips)
        with arm.bus.lock, can_bus.lock:
            assert servo.get_reg("Bus_Watchdog") == -1 and motor.mode == 0
            ((last, at),) = servo.watchdog_trips
            assert at - last == pytest.approx(0.02, abs=1e-9)
            ((last, at),) = motor.watchdog_trips
            assert at - last == pytest.approx(0.02, abs=1e-9)
