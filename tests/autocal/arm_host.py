"""A simulated LeRobot arm with physics in its own process, on a pseudo-terminal, running on the wall clock.

``python tests/autocal/arm_host.py ROBOT [SEED]`` prints ``port: /dev/pts/N`` and then answers one command per line
on standard input:

- ``state``: one JSON line, motor name → every register of its control table (the oracle of the interruption
  tests: torque flags and register values as the simulated servo holds them, whatever robocal printed);
- ``vanish``: the device disappears (the pseudo-terminal is closed, as when a USB cable is pulled); answers ``ok``;
- ``quit``: stops.

robocal talks to it as to a real arm (``--port /dev/pts/N``, the wall clock): the servos' firmware integrates its
joint plant up to the wall clock at every packet, so a process held up by the machine's load sees the arm move on.
"""

from __future__ import annotations

import json
import sys
import time

from robocal.backends.servo_ratings import RATINGS
from robocal.backends.sim.arm_physics import attach_physics
from robocal.backends.sim.lerobot_arms import SimArm, seeded_truth
from robocal.backends.sim.physics import SimClock
from robocal.workflows.lerobot import robot_spec
from robocal.workflows.lerobot.auto import auto_section


class WallClock(SimClock):
    """Simulated time that is the wall clock: packets do not move it, the world does."""

    def __init__(self) -> None:
        super().__init__()
        self._t0 = time.monotonic()

    def now(self) -> float:
        return time.monotonic() - self._t0

    def advance(self, dt_s: float) -> float:
        return self.now()


def main() -> None:
    robot = sys.argv[1]
    seed = int(sys.argv[2]) if len(sys.argv) > 2 else 1
    spec = robot_spec(robot)
    section = auto_section(robot)
    expected = {
        j.name: (j.lower_deg, j.upper_deg)
        for j in section.searched_joints
        if j.lower_deg is not None and j.upper_deg is not None
    }
    spread = max(0.0, 0.5 * section.span_tolerance_deg - 0.5)
    truth = seeded_truth(spec.name, seed, expected_deg=expected, stop_spread_deg=spread)
    push = {}
    for m in spec.motors:
        joint = section.joint(m.name)
        fraction = joint.torque_fraction if joint is not None and joint.searched else 0.25
        push[m.name] = fraction * RATINGS[m.model].stall_torque_nm
    previous = {  # a previous calibration in the EEPROM, which an interrupted run must leave as it was
        m.name: {"Homing_Offset": -100 - i, "Min_Position_Limit": 500 + i, "Max_Position_Limit": 3500 - i}
        for i, m in enumerate(spec.motors)
    }
    arm = SimArm(spec, truth=truth, eeprom=previous)
    clock = WallClock()
    attach_physics(arm, clock, search_torque_nm=push, seed=seed)
    with arm:
        print(f"port: {arm.port}", flush=True)
        for line in sys.stdin:
            cmd = line.strip()
            if cmd == "state":
                with arm.bus.lock:
                    state = {
                        m.name: {r: arm.servo(m.name).get_reg(r) for r in arm.servo(m.name).table}
                        for m in spec.motors
                    }
                print(json.dumps(state), flush=True)
            elif cmd == "vanish":
                arm.bus.stop()
                print("ok", flush=True)
            elif cmd == "quit":
                break


if __name__ == "__main__":
    main()
