"""A minimal 1-DOF joint with spring-damper stops, friction and gravity, driven like a PD motor (tests only).

It stands in for a driver so the core stop search can be tested with synthetic traces; the wire-level
simulators live in robocal.backends.sim.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from robocal.core.stop_search import Command, StopSample, StopSearch


@dataclass
class Plant:
    q_lo: float = -1.0
    q_hi: float = 1.0
    k_lo: float = 300.0
    k_hi: float = 300.0
    missing_hi: bool = False
    obstacle: float | None = None  # a block at this angle (upper side), stiffness k_hi
    inertia: float = 0.01
    coulomb: float = 0.05
    stiction: float = 0.1
    viscous: float = 0.02
    stop_damping: float = 0.5
    gravity: Callable[[float], float] = lambda q: 0.0
    kp: float = 10.0
    kd: float = 0.2
    noise_rad: float = 0.0002
    ticks: int = 4096
    period_s: float = 0.01
    overload_torque: float | None = None  # latch when |tau| >= this for overload_time_s
    overload_time_s: float = 0.3
    silent_beyond: float | None = None  # no replies once q > this
    seed: int = 0
    q: float = 0.0
    v: float = 0.0
    t: float = 0.0
    tau: float = 0.0
    latched: bool = False
    _over: float = 0.0
    rng: np.random.Generator = field(init=False)
    peak: float = 0.0

    def __post_init__(self) -> None:
        self.rng = np.random.default_rng(self.seed)

    def stop_torque(self, q: float, v: float) -> float:
        tau = 0.0
        if q < self.q_lo:
            tau += self.k_lo * (self.q_lo - q) - self.stop_damping * min(v, 0.0)
        hi = self.obstacle if self.obstacle is not None else (None if self.missing_hi else self.q_hi)
        if hi is not None and q > hi:
            tau -= self.k_hi * (q - hi) + self.stop_damping * max(v, 0.0)
        return tau

    def motor(self, cmd: Command, q: float, v: float) -> float:
        if self.latched or cmd.action == "limp":
            return 0.0
        if cmd.action == "push":
            d = 1.0 if cmd.q_target_rad > q else -1.0
            tau = d * cmd.torque_limit_nm - self.kd * v
        else:
            tau = self.kp * (cmd.q_target_rad - q) + self.kd * (cmd.v_target_rad_s - v)
        lim = cmd.torque_limit_nm
        return float(np.clip(tau, -lim, lim))

    def run(self, cmd: Command) -> StopSample:
        dt = 0.001
        n = round(self.period_s / dt)
        if cmd.action == "reread":
            self.latched = False
            self._over = 0.0
        for _ in range(n):
            tau_m = self.motor(cmd, self.q, self.v)
            self.tau = tau_m
            self.peak = max(self.peak, abs(tau_m))
            ext = tau_m + self.gravity(self.q) + self.stop_torque(self.q, self.v)
            if abs(self.v) < 1e-4 and abs(ext) <= self.stiction:
                self.v = 0.0
            else:
                fr = self.coulomb * math.copysign(1.0, self.v if self.v != 0 else ext) + self.viscous * self.v
                self.v += (ext - fr) / self.inertia * dt
            self.q += self.v * dt
            self.t += dt
            if self.overload_torque is not None and abs(tau_m) >= self.overload_torque:
                self._over += dt
                if self._over >= self.overload_time_s:
                    self.latched = True
            else:
                self._over = 0.0
        if self.silent_beyond is not None and self.q > self.silent_beyond and cmd.action != "reread":
            return StopSample(self.t, math.nan, ok=False)
        res = 2 * math.pi / self.ticks
        q_meas = round((self.q + self.rng.normal(0, self.noise_rad)) / res) * res
        return StopSample(self.t, q_meas, self.v, self.tau, True, self.latched)

    def sample(self) -> StopSample:
        return StopSample(self.t, self.q, self.v, self.tau)


def run_search(plant: Plant, search: StopSearch, max_steps: int = 100_000) -> list[Command]:
    cmds = [search.start(plant.sample())]
    for _ in range(max_steps):
        if search.done:
            break
        cmds.append(search.step(plant.run(cmds[-1])))
    return cmds


class PlantDriver:
    """A :class:`robocal.workflows.autocal.job.JointDriver` over a :class:`Plant` (no wire; tests of the workflow)."""

    def __init__(self, name: str, plant: Plant, interrupt_after: int | None = None) -> None:
        self.name = name
        self.plant = plant
        self.limp_count = 0
        self.is_limp = False
        self.steps = 0
        self.interrupt_after = interrupt_after

    def read(self) -> StopSample:
        return self.plant.sample()

    def execute(self, cmd: Command) -> StopSample:
        self.steps += 1
        if self.interrupt_after is not None and self.steps >= self.interrupt_after:
            raise KeyboardInterrupt
        self.is_limp = cmd.action == "limp"
        return self.plant.run(cmd)

    def limp(self) -> None:
        self.limp_count += 1
        self.is_limp = True
        self.plant.run(Command("limp"))
