"""The OpenArm's stop search when robocal is held up: never a stop it did not meet (issues 26 item 4, 31).

The fault soaks of 2026-11-29 (load average 10-20, no fault injected) saw the gripper's search end
``span_mismatch`` with spans of 12-46° instead of 60°. Traced (every command and reading of the searched motor):
on the loaded machine robocal's loop read the joint every ~50 ms instead of every 10 ms, so the target advanced in
steps the joint followed stick-slip, resting between them; a reply then came later than the 0.1 s reply wait (lost,
for robocal), and its re-read agreed with the last good reading, which happened to be at rest: ``no-reply+reread``
took that for the upper stop, 24° short of it. Here the same loop runs on the simulated arm's clock (every reading
of the gripper's upper search 50 ms apart, one reply lost while the joint rests in free travel), judged by the
simulator's truth: the span and the zero the search finds are the simulated stops'.

A motor whose TIMEOUT tripped while robocal was held up is a fault, never cleared by the re-read of a lost reply.
"""

from __future__ import annotations

import contextlib
import json
import math
from collections.abc import Callable, Sequence
from importlib import resources
from pathlib import Path
from typing import Any

import pytest

pytest.importorskip("can")

from robocal.backends.damiao.protocol import MitCommand, MotorState
from robocal.errors import CalibTimeoutError, DeviceError
from robocal.formats import read_calibration
from robocal.workflows.autocal import sweep as sweep_module
from robocal.workflows.autocal.damiao import SimAutoOpenArm, sim_openarm_opener
from robocal.workflows.autocal.model import AutoCalAbortedError, AutoCalFailedError
from robocal.workflows.autocal.sweep import SweepAutoRequest, run_sweep_auto

pytestmark = pytest.mark.timeout(600)  # a loaded machine: the in-process simulator shares this process

GRIPPER = "openarm_right_gripper_motor"
URDF = Path(str(resources.files("robocal").joinpath("data", "openarm_v10_right.urdf")))
SPEED_RAD_S = math.radians(10.0)  # the profile's search speed
SLOW_LOOP_S = 0.03  # robocal held up this long after each exchange of the upper search: a reading every ~40 ms


class LoadedLoop:
    """The gripper's exchanges as a loaded machine makes them (wraps ``bus.mit`` and ``clock.sleep`` of the sim).

    In the upper search (the joint 32° or more above its lower stop and 10° or more below its upper one, pushed
    up at the search speed or less), once the stall test is armed (4° of travel, a reading at 70 % of the speed),
    each wait for the next control period lasts :data:`SLOW_LOOP_S` longer (robocal descheduled: no frame
    meanwhile); once ten such readings went by and one shows the joint at rest, the
    next reply is lost after its frame reached the motor (a reply later than the wait). ``hold_s``: robocal is also
    held up this long just before that lost exchange (longer than the motor's TIMEOUT: it trips).
    """

    def __init__(self, sim: SimAutoOpenArm, hold_s: float = 0.0) -> None:
        self.sim = sim
        self.real_mit: Callable[[str, MitCommand], MotorState] = sim.bus.mit
        self.real_sleep: Callable[[float], float] = sim.clock.sleep
        self.hold_s = hold_s
        self.slow = 0
        self.lose_next = False
        self.fast_seen = False
        self.start_rad: float | None = None
        self.lost_at_joint_rad: list[float] = []

    def _upper_search(self, cmd: MitCommand) -> bool:
        j = next(j for j in self.sim.arm.joints if j.name == "gripper")
        q = self.sim.arm.joint_rad("gripper")
        return (
            j.stop_lower_rad + math.radians(32) < q < j.stop_upper_rad - math.radians(10)
            and 0.0 <= cmd.velocity_rad_s <= SPEED_RAD_S + 1e-9
            and cmd.kp > 0
        )

    def mit(self, name: str, cmd: MitCommand) -> MotorState:
        if name != GRIPPER or self.lost_at_joint_rad or not (self.lose_next or self._upper_search(cmd)):
            return self.real_mit(name, cmd)
        if self.lose_next:
            with contextlib.suppress(DeviceError):  # the frame reached the motor; its reply came too late for robocal
                self.real_mit(name, cmd)
            self.lost_at_joint_rad.append(self.sim.arm.joint_rad("gripper"))
            raise CalibTimeoutError("no reply within 0.1 s (injected: a reply later than the wait)")
        state = self.real_mit(name, cmd)
        if self.start_rad is None:
            self.start_rad = state.position_rad
        self.fast_seen = self.fast_seen or state.velocity_rad_s >= 0.7 * SPEED_RAD_S
        if self.slow or (self.fast_seen and state.position_rad - self.start_rad > math.radians(4)):
            self.slow += 1  # the stall test is armed (4° of travel, a reading at 70 % of the speed): load comes
        self.lose_next = self.slow >= 10 and abs(state.velocity_rad_s) < 0.5 * SPEED_RAD_S
        return state

    def sleep(self, dt_s: float) -> float:
        if self.slow and not self.lost_at_joint_rad:
            dt_s += SLOW_LOOP_S + (self.hold_s if self.lose_next else 0.0)
        return self.real_sleep(dt_s)


def _loaded_opener(holder: list[SimAutoOpenArm], loops: list[LoadedLoop], hold_s: float) -> Callable[..., Any]:
    inner = sim_openarm_opener(holder)

    def open_(spec: Any, joints: Sequence[Any], profile: Any) -> tuple[Any, Any, Any]:
        drivers, clock, close = inner(spec, joints, profile)
        loop = LoadedLoop(holder[-1], hold_s)
        holder[-1].bus.mit = loop.mit  # the drivers call bus.mit and clock.sleep: the gripper's go through the loop
        holder[-1].clock.sleep = loop.sleep
        loops.append(loop)
        return drivers, clock, close

    return open_


def _run(tmp_path: Path, seed: int, hold_s: float = 0.0) -> tuple[SimAutoOpenArm, LoadedLoop, Any]:
    holder: list[SimAutoOpenArm] = []
    loops: list[LoadedLoop] = []
    request = SweepAutoRequest(
        URDF, f"sim:openarm?seed={seed}", tmp_path / "cal.yaml", robot="openarm_follower_right", joints=[GRIPPER],
        report=tmp_path / "rep.json",
    )  # fmt: skip
    try:
        try:
            outcome: Any = run_sweep_auto(request, open_drivers_fn=_loaded_opener(holder, loops, hold_s))
        except Exception as exc:  # judged below, after the simulator stopped
            outcome = exc
    finally:
        for sim in holder:
            sim.close()
    return holder[0], loops[0], outcome


@pytest.mark.parametrize("seed", [3, pytest.param(8, marks=pytest.mark.slow)])
def test_a_reply_lost_while_the_slow_loops_joint_rests_in_free_travel_is_no_stop(tmp_path: Path, seed: int) -> None:
    sim, loop, outcome = _run(tmp_path, seed)
    assert len(loop.lost_at_joint_rad) == 1 and loop.slow >= 10  # the situation of the soak was reached
    joint = next(j for j in sim.arm.joints if j.name == "gripper")
    assert loop.lost_at_joint_rad[0] < joint.stop_upper_rad - math.radians(10)  # in free travel, far from the stop
    assert not isinstance(outcome, Exception), outcome  # before the fix: span_mismatch, span ~35° (seed 3)
    cf = read_calibration(tmp_path / "cal.yaml")
    got = cf.calibration.homing_offset[cf.calibration.index(GRIPPER)]
    assert abs(math.degrees(got - sim.arm.zero_error_rad("gripper"))) < 0.1  # the simulator's zero
    auto = json.loads((tmp_path / "rep.json").read_text())["auto"]["joints"][GRIPPER]
    true_span_deg = math.degrees(joint.stop_upper_rad - joint.stop_lower_rad)
    assert auto["code"] == "ok" and abs(auto["span_deg"] - true_span_deg) < 0.5  # the simulator's stops
    assert not sim.arm.motors["gripper"].enabled


@pytest.mark.slow
def test_a_timeout_tripped_while_robocal_was_held_up_is_a_fault_not_cleared_by_the_reread(tmp_path: Path) -> None:
    sim, loop, outcome = _run(tmp_path, 3, hold_s=0.8)  # held up 0.8 s: the 0.5 s TIMEOUT trips (state 0xD)
    motor = sim.arm.motors["gripper"]
    assert len(loop.lost_at_joint_rad) == 1 and len(motor.lost_comm_at_s) == 1  # it did trip
    # before: the gap failed the search (no_reply), and the time read after it re-enabled the motor: "reports
    # communication lost", not that robocal was held up; without the gap bound, the re-read's 0xFB would wipe the 0xD
    assert isinstance(outcome, AutoCalAbortedError), outcome
    assert "TIMEOUT" in str(outcome) and "robocal was held up" in str(outcome)
    assert not motor.enabled and motor.ram[9] == 0  # limp, its TIMEOUT put back
    assert motor.requests.get("clear error", 0) == 0  # the trip was never cleared
    assert not (tmp_path / "cal.yaml").exists()


@pytest.mark.slow
def test_a_failed_joint_stays_limp_until_the_run_ends(tmp_path: Path) -> None:
    """The joint's time used to be read off the motor after its failure, which switched it on again (enable,
    damping only, TIMEOUT armed) until the run's last limp."""
    holder: list[SimAutoOpenArm] = []
    request = SweepAutoRequest(
        URDF, f"sim:openarm?seed=3&missing={GRIPPER}", tmp_path / "cal.yaml", robot="openarm_follower_right",
        joints=[GRIPPER],
    )  # fmt: skip
    enables: list[int] = []
    real_limp_all = sweep_module.limp_all

    def limp_all(drivers: Any) -> list[str]:  # the run's last limp: how often was the gripper enabled by then
        enables.append(holder[0].arm.motors["gripper"].requests.get("enable", 0))
        return real_limp_all(drivers)

    try:
        sweep_module.limp_all = limp_all  # type: ignore[assignment]
        with pytest.raises(AutoCalFailedError, match="missing_stop"):
            run_sweep_auto(request, open_drivers_fn=sim_openarm_opener(holder))
    finally:
        sweep_module.limp_all = real_limp_all  # type: ignore[assignment]
        for sim in holder:
            sim.close()
    assert enables and enables[0] == 1  # before: 2 (switched on again after its failed search)
    assert not holder[0].arm.motors["gripper"].enabled
