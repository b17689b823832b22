"""A 1-DOF joint plant on a simulated clock: the physics behind the simulated motors (pure numpy).

One :class:`JointPlant` is one joint: a rigid body of inertia ``J`` on the motor side, driven by a motor torque
that follows a saturated PD law (:class:`Drive`, the shape every simulated firmware reduces to), loaded by

* Coulomb + viscous friction with breakaway: a joint at rest stays at rest while the torque it needs to be held
  is at most ``stiction_nm`` (> the running friction ``coulomb_nm``);
* gravity ``τ_g(q) = −gravity_nm · sin(q − gravity_zero_rad)`` (0 at ``gravity_zero_rad``, the hanging pose);
* hard stops as one-sided spring-dampers (stiffness per side, damping from a damping ratio; a stop pushes, never
  pulls); a missing stop is ``None`` (continuous joint);
* optionally a mid-travel obstacle (a third one-sided wall) and a cable snag (a one-sided spring whose stiffness
  rises with the stretch: ``τ = −(k₁·x + k₃·x³)``);
* gear backlash: the link (where stops, gravity, obstacle and cable act) sits within ``±backlash_rad/2`` of the
  motor; a load torque presses it to one side of the gap; with no load it stays where it is (play operator).

Time is simulated: :meth:`JointPlant.run_until` / :meth:`JointPlant.advance` integrate with a fixed step
``dt_s`` (0.5 ms) and a linearly implicit Euler scheme (stop, PD, damping and cable stiffness treated implicitly),
so the stiff end (1000 N·m/rad stops on 10⁻⁴ kg·m²) stays stable. Nothing reads the wall clock.

Readings (:meth:`JointPlant.read`) are quantised to ``counts_per_rev`` with Gaussian noise (seeded RNG), from the
motor side or the link side (``encoder_on_link``: a servo's output-shaft encoder).

Firmware-neutral faults, for a stop search to face without a wire: an :class:`OverloadLatch` (after
``protection_s`` at ``|τ| ≥ threshold_nm`` the output is limited to ``latched_limit_nm`` and
:attr:`Reading.overload` is set until :meth:`JointPlant.clear_overload`) and a motor that stops answering while
it is pressed into a wall harder than ``silent_above_nm`` (:attr:`Reading.answers` is False; the motor still
hears and obeys commands, only its replies are lost).

Typical use (a stop search in core, tested without any wire)::

    nominal = PlantParams(stop_lower_rad=-1.0, stop_upper_rad=1.2, stiffness_lower=600, stiffness_upper=600)
    plant = make_plant(Scenario(stiction_ratio=0.8), nominal, search_torque_nm=1.5, seed=3)
    drive = Drive(kp_nm_rad=10, kd_nms_rad=0.2, q_ref_rad=0.3, tau_max_nm=1.5)
    plant.advance(0.01, drive)          # 10 ms of simulated time under this command
    r = plant.read()                    # Reading(t_s, q_rad, v_rad_s, tau_nm, overload, answers)

The simulated Robstride, Feetech and Dynamixel firmwares (``robstride.sim``, ``sim.servo`` with ``feetech.sim`` / ``dynamixel.sim``) turn their wire
commands into a :class:`Drive` and step a plant to the simulated time of each request.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from ...errors import UsageError

__all__ = [
    "Drive",
    "JointPlant",
    "OverloadLatch",
    "PlantParams",
    "Reading",
    "Scenario",
    "SimClock",
    "make_plant",
]



class SimClock:
    """A simulated clock owned by a test or a workflow: it moves only when told (:meth:`sleep`, :meth:`advance`).

    The simulated buses advance it by their latency per transfer (:meth:`advance`, from their thread), so a
    search loop that sleeps on it (:meth:`sleep`, from the host's thread) and the plants it drives share one time
    line, independent of the wall clock. :meth:`sleep` first lets every registered bus finish the packets already
    sent to it (a write that gets no reply is applied before the time moves on), so runs are deterministic.
    """

    def __init__(self, t0_s: float = 0.0) -> None:
        self._t = float(t0_s)
        self._settlers: list[Callable[[], None]] = []

    def now(self) -> float:
        """Simulated seconds."""
        return self._t

    def advance(self, dt_s: float) -> float:
        """Move time forward by ``dt_s`` ≥ 0; returns the new time (the simulators' side)."""
        if not dt_s >= 0.0:
            raise UsageError(f"a simulated clock moves forward only (dt {dt_s!r})")
        self._t += dt_s
        return self._t

    def sleep(self, dt_s: float) -> float:
        """The host waits ``dt_s``: pending packets are handled first, then time moves on; returns the new time."""
        for settle in list(self._settlers):
            settle()
        return self.advance(dt_s)

    def add_settler(self, settle: Callable[[], None]) -> None:
        """Register a bus's "finish what was sent" (called by :meth:`sleep`)."""
        self._settlers.append(settle)

    def remove_settler(self, settle: Callable[[], None]) -> None:
        """Unregister it (a bus that stopped)."""
        if settle in self._settlers:
            self._settlers.remove(settle)


@dataclass(frozen=True)
class Drive:
    """The motor torque law: ``τ = clip(kp·(q_ref − q) + kd·(v_ref − v) + τ_ff, ±τ_max)`` (motor side, rad).

    ``Drive()`` is limp (zero torque). A constant torque is ``Drive(tau_ff_nm=τ, tau_max_nm=|τ|)``.
    """

    kp_nm_rad: float = 0.0
    kd_nms_rad: float = 0.0
    q_ref_rad: float = 0.0
    v_ref_rad_s: float = 0.0
    tau_ff_nm: float = 0.0
    tau_max_nm: float = 0.0

    def torque(self, q_rad: float, v_rad_s: float) -> float:
        """The saturated motor torque at state (q, v), N·m."""
        raw = self.kp_nm_rad * (self.q_ref_rad - q_rad) + self.kd_nms_rad * (self.v_ref_rad_s - v_rad_s)
        raw += self.tau_ff_nm
        return max(-self.tau_max_nm, min(self.tau_max_nm, raw))


@dataclass(frozen=True)
class PlantParams:
    """Physical parameters of one joint (SI units, joint/output frame).

    Attributes:
        inertia_kgm2: Reflected inertia at the joint.
        coulomb_nm: Running (Coulomb) friction.
        stiction_nm: Breakaway friction (≥ ``coulomb_nm``).
        viscous_nms_rad: Viscous friction.
        gravity_nm: Gravity torque amplitude; ``τ_g = −gravity_nm·sin(q − gravity_zero_rad)``.
        gravity_zero_rad: Where gravity torque is zero (the hanging pose).
        backlash_rad: Total gear play between motor and link.
        stop_lower_rad: Lower hard stop (None: none).
        stop_upper_rad: Upper hard stop (None: none).
        stiffness_lower: Lower stop stiffness, N·m/rad.
        stiffness_upper: Upper stop stiffness, N·m/rad.
        stop_damping_ratio: Stop damping ``c = 2·ζ·√(k·J)``.
        obstacle_rad: A mid-travel block (None: none).
        obstacle_side: +1 blocks motion above ``obstacle_rad``, −1 below.
        obstacle_stiffness: Its stiffness, N·m/rad.
        cable_rad: Where a cable starts to stretch (None: no cable).
        cable_side: +1: stretches above ``cable_rad``; −1 below.
        cable_k1_nm_rad: Linear cable stiffness.
        cable_k3_nm_rad3: Cubic stiffening.
        counts_per_rev: Encoder resolution (0: no quantisation).
        noise_rad: Encoder noise σ.
        encoder_on_link: Read the link (output shaft) rather than the motor side of the backlash.
        dt_s: Integration step.
    """

    inertia_kgm2: float = 0.005
    coulomb_nm: float = 0.02
    stiction_nm: float = 0.03
    viscous_nms_rad: float = 0.01
    gravity_nm: float = 0.0
    gravity_zero_rad: float = 0.0
    backlash_rad: float = 0.0
    stop_lower_rad: float | None = -1.0
    stop_upper_rad: float | None = 1.0
    stiffness_lower: float = 600.0
    stiffness_upper: float = 600.0
    stop_damping_ratio: float = 0.5
    obstacle_rad: float | None = None
    obstacle_side: int = 1
    obstacle_stiffness: float = 300.0
    cable_rad: float | None = None
    cable_side: int = 1
    cable_k1_nm_rad: float = 0.0
    cable_k3_nm_rad3: float = 0.0
    counts_per_rev: int = 4096
    noise_rad: float = 0.0
    encoder_on_link: bool = False
    dt_s: float = 0.0005

    def __post_init__(self) -> None:
        positive = {"inertia_kgm2": self.inertia_kgm2, "dt_s": self.dt_s}
        for name, value in positive.items():
            if not (math.isfinite(value) and value > 0):
                raise UsageError(f"plant {name} must be a positive number, not {value!r}")
        nonneg = {
            "coulomb_nm": self.coulomb_nm,
            "viscous_nms_rad": self.viscous_nms_rad,
            "backlash_rad": self.backlash_rad,
            "stiffness_lower": self.stiffness_lower,
            "stiffness_upper": self.stiffness_upper,
            "stop_damping_ratio": self.stop_damping_ratio,
            "obstacle_stiffness": self.obstacle_stiffness,
            "cable_k1_nm_rad": self.cable_k1_nm_rad,
            "cable_k3_nm_rad3": self.cable_k3_nm_rad3,
            "noise_rad": self.noise_rad,
            "counts_per_rev": float(self.counts_per_rev),
        }
        for name, value in nonneg.items():
            if not (math.isfinite(value) and value >= 0):
                raise UsageError(f"plant {name} must be a number >= 0, not {value!r}")
        if not (math.isfinite(self.stiction_nm) and self.stiction_nm >= self.coulomb_nm):
            raise UsageError(
                f"plant stiction_nm {self.stiction_nm!r} must be >= coulomb_nm {self.coulomb_nm!r}"
            )
        lo, hi = self.stop_lower_rad, self.stop_upper_rad
        if lo is not None and hi is not None and not lo < hi:
            raise UsageError(f"plant stops must satisfy lower < upper, not {lo!r} >= {hi!r}")
        if self.obstacle_side not in (-1, 1) or self.cable_side not in (-1, 1):
            raise UsageError("plant obstacle_side and cable_side are +1 or -1")


@dataclass(frozen=True)
class OverloadLatch:
    """A firmware overload protection: ``|τ| ≥ threshold_nm`` for ``protection_s`` latches the fault.

    While latched the output torque is limited to ``latched_limit_nm`` (0: torque off) until cleared.
    """

    threshold_nm: float
    protection_s: float
    latched_limit_nm: float = 0.0


@dataclass(frozen=True)
class Reading:
    """What a motor could report at one instant.

    Attributes:
        t_s: Simulated time.
        q_rad: Encoder position (quantised, noisy; motor or link side per ``encoder_on_link``).
        v_rad_s: Velocity (true).
        tau_nm: Motor torque applied (after saturation and any overload limit).
        overload: The overload latch is set.
        answers: The motor answers (False: its reply is lost).
    """

    t_s: float
    q_rad: float
    v_rad_s: float
    tau_nm: float
    overload: bool
    answers: bool


def _sign(x: float) -> float:
    return 1.0 if x > 0 else (-1.0 if x < 0 else 0.0)


_Rest = tuple["Drive", "OverloadLatch | None", "PlantParams", float, float, bool, float, float]  # …, q, link, latch, τs


class JointPlant:
    """One joint integrated on a simulated clock (see the module docstring).

    Args:
        params: Physical parameters.
        seed: Seed of the encoder noise.
        q0_rad: Initial position (motor side); default: midway between the stops (or 0).
        overload: Overload protection of the firmware (None: none).
        silent_above_nm: The motor's replies are lost while a wall presses the link harder than this (None: never).
    """

    def __init__(
        self,
        params: PlantParams,
        *,
        seed: int = 0,
        q0_rad: float | None = None,
        overload: OverloadLatch | None = None,
        silent_above_nm: float | None = None,
    ) -> None:
        self.params = params
        self.overload = overload
        self.silent_above_nm = silent_above_nm
        self._rng = np.random.default_rng(seed)
        lo, hi = params.stop_lower_rad, params.stop_upper_rad
        if q0_rad is None:
            q0_rad = 0.5 * (lo + hi) if lo is not None and hi is not None else 0.0
        self.q_rad = float(q0_rad)
        self.v_rad_s = 0.0
        self.link_rad = self.q_rad
        self.tau_motor_nm = 0.0
        self.tau_wall_nm = 0.0
        """Torque the walls (stops, obstacle) put on the link at the last step."""
        self.peak_tau_motor_nm = 0.0
        self.latched = False
        self._over_s = 0.0
        self._stuck = True
        self._steps = 0
        self._rest: _Rest | None = None  # the last resting check that held (see _resting)
        j = params.inertia_kgm2
        z = params.stop_damping_ratio
        walls: list[tuple[float, float, float, float]] = []  # (position, side, k, c)
        if lo is not None:
            walls.append((lo, -1.0, params.stiffness_lower, 2 * z * math.sqrt(params.stiffness_lower * j)))
        if hi is not None:
            walls.append((hi, 1.0, params.stiffness_upper, 2 * z * math.sqrt(params.stiffness_upper * j)))
        if params.obstacle_rad is not None:
            k = params.obstacle_stiffness
            walls.append((params.obstacle_rad, float(params.obstacle_side), k, 2 * z * math.sqrt(k * j)))
        self._walls = tuple(walls)

    # ------------------------------------------------------------------------------------------- state
    @property
    def t_s(self) -> float:
        """Simulated time of the plant (a whole number of steps)."""
        return self._steps * self.params.dt_s

    def set_state(self, q_rad: float, v_rad_s: float = 0.0) -> None:
        """Put the joint somewhere (by hand); the link takes the middle of the backlash gap."""
        self.q_rad, self.v_rad_s, self.link_rad = float(q_rad), float(v_rad_s), float(q_rad)
        self._stuck = v_rad_s == 0.0

    def clear_overload(self) -> None:
        """Reset the overload latch (what a torque off/on does on the firmwares that allow it)."""
        self.latched = False
        self._over_s = 0.0

    def gravity_nm(self, q_rad: float) -> float:
        """Gravity torque on the link at ``q_rad``."""
        p = self.params
        return -p.gravity_nm * math.sin(q_rad - p.gravity_zero_rad) if p.gravity_nm else 0.0

    def answers(self) -> bool:
        """False while the motor's replies are lost (pressed into a wall harder than ``silent_above_nm``)."""
        return self.silent_above_nm is None or abs(self.tau_wall_nm) <= self.silent_above_nm

    def read(self) -> Reading:
        """Encoder reading and motor state now (draws noise from the seeded RNG)."""
        p = self.params
        q = self.link_rad if p.encoder_on_link else self.q_rad
        if p.noise_rad > 0:
            q += float(self._rng.normal(0.0, p.noise_rad))
        if p.counts_per_rev:
            res = math.tau / p.counts_per_rev
            q = round(q / res) * res
        return Reading(self.t_s, q, self.v_rad_s, self.tau_motor_nm, self.latched, self.answers())

    # ----------------------------------------------------------------------------------------- loads
    def _static_load(self, x: float) -> float:
        """Gravity + walls + cable on a link at rest at ``x`` (no damping)."""
        tau = self.gravity_nm(x)
        for pos, side, k, _c in self._walls:
            pen = (x - pos) * side
            if pen > 0:
                tau -= side * k * pen
        p = self.params
        if p.cable_rad is not None:
            s = (x - p.cable_rad) * p.cable_side
            if s > 0:
                tau -= p.cable_side * (p.cable_k1_nm_rad * s + p.cable_k3_nm_rad3 * s**3)
        return tau

    def _link(self, q: float) -> bool:
        """Place the link in the backlash gap around motor position ``q``; True when it is pressed to a side."""
        half = 0.5 * self.params.backlash_rad
        if half == 0.0:
            self.link_rad = q
            return True
        lo, hi = q - half, q + half
        t_lo, t_hi = self._static_load(lo), self._static_load(hi)
        if t_lo > 0 and t_hi > 0:
            self.link_rad = hi
            return True
        if t_lo < 0 and t_hi < 0:
            self.link_rad = lo
            return True
        self.link_rad = min(hi, max(lo, self.link_rad))
        return False

    def _load(self, x: float, v: float) -> tuple[float, float, float, float]:
        """External torque on the engaged link at (x, v): (τ, dτ/dq stiffness, dτ/dv damping, wall τ)."""
        tau = self.gravity_nm(x)
        k_sum = c_sum = wall = 0.0
        for pos, side, k, c in self._walls:
            pen = (x - pos) * side
            if pen > 0:
                t = -side * (k * pen + c * v * side)
                if t * side <= 0:  # pushes back (a wall never pulls)
                    wall += t
                    k_sum += k
                    c_sum += c
        tau += wall
        p = self.params
        if p.cable_rad is not None:
            s = (x - p.cable_rad) * p.cable_side
            if s > 0:
                tau -= p.cable_side * (p.cable_k1_nm_rad * s + p.cable_k3_nm_rad3 * s**3)
                k_sum += p.cable_k1_nm_rad + 3 * p.cable_k3_nm_rad3 * s * s
        return tau, k_sum, c_sum, wall

    # ------------------------------------------------------------------------------------ integration
    def step(self, drive: Drive) -> None:
        """Integrate one step ``dt_s`` under ``drive``."""
        p = self.params
        dt, j = p.dt_s, p.inertia_kgm2
        q, v = self.q_rad, self.v_rad_s
        engaged = self._link(q)
        if engaged:
            tau_ext, k_ext, c_ext, self.tau_wall_nm = self._load(self.link_rad, v)
        else:
            tau_ext = k_ext = c_ext = self.tau_wall_nm = 0.0
        tau_max = drive.tau_max_nm
        if self.latched and self.overload is not None:
            tau_max = min(tau_max, self.overload.latched_limit_nm)
        raw = drive.kp_nm_rad * (drive.q_ref_rad - q) + drive.kd_nms_rad * (drive.v_ref_rad_s - v)
        raw += drive.tau_ff_nm
        if abs(raw) < tau_max:
            tau_m, k_m, c_m = raw, drive.kp_nm_rad, drive.kd_nms_rad
        else:
            tau_m, k_m, c_m = math.copysign(tau_max, raw), 0.0, 0.0
        self.tau_motor_nm = tau_m
        self.peak_tau_motor_nm = max(self.peak_tau_motor_nm, abs(tau_m))
        if self.overload is not None and not self.latched:
            self._over_s = self._over_s + dt if abs(tau_m) >= self.overload.threshold_nm else 0.0
            if self._over_s >= self.overload.protection_s - 1e-12:
                self.latched = True
        f = tau_m + tau_ext - p.viscous_nms_rad * v
        if self._stuck:
            if abs(f) <= p.stiction_nm:
                self._steps += 1
                return
            self._stuck = False
            fric = -p.coulomb_nm * _sign(f)
        else:
            fric = -p.coulomb_nm * _sign(v)
        big_k = k_m + k_ext
        big_d = c_m + c_ext + p.viscous_nms_rad
        v1 = (j * v / dt + f + fric + big_d * v) / (j / dt + big_k * dt + big_d)
        direction = v if v != 0.0 else f
        if v1 * direction < 0 or v1 == 0.0:
            v1 = 0.0
            self._stuck = True
        self.q_rad = q + v1 * dt
        self.v_rad_s = v1
        self._steps += 1

    def run_until(self, t_s: float, drive: Drive) -> None:
        """Integrate under ``drive`` up to simulated time ``t_s`` (nothing happens if it is in the past)."""
        target = math.floor(t_s / self.params.dt_s + 1e-9)
        while self._steps < target:
            if self._stuck and (self._rested(drive) or self._resting(drive)):
                self._steps = target  # at rest under a constant drive: exactly what the steps would do
                return
            self.step(drive)

    def hold_until(self, t_s: float, drive: Drive) -> bool:
        """If the joint rests under ``drive`` as last found, move its time to ``t_s`` (as :meth:`run_until`): True."""
        if not (self._stuck and self._rested(drive)):
            return False
        self._steps = max(self._steps, math.floor(t_s / self.params.dt_s + 1e-9))
        return True

    def advance(self, duration_s: float, drive: Drive) -> None:
        """Integrate under ``drive`` for ``duration_s`` of simulated time."""
        self.run_until(self.t_s + duration_s, drive)

    def _rested(self, drive: Drive) -> bool:
        """:meth:`_resting` held last time for this very drive and state (it is a pure function of them): again."""
        rest = self._rest
        if rest is None:
            return False
        drive0, overload0, params0, q0, link0, latched0, tau_m, wall = rest
        if not (
            drive0 is drive
            and params0 is self.params
            and overload0 is self.overload
            and q0 == self.q_rad
            and link0 == self.link_rad
            and latched0 == self.latched
        ):
            return False
        self.tau_motor_nm, self.tau_wall_nm = tau_m, wall
        self._over_s = 0.0
        return True

    def _resting(self, drive: Drive) -> bool:
        """A stuck joint whose holding torque stays within the breakaway (and no overload timer running)."""
        q = self.q_rad
        engaged = self._link(q)
        tau_ext, _, _, wall = self._load(self.link_rad, 0.0) if engaged else (0.0, 0.0, 0.0, 0.0)
        tau_m = drive.torque(q, 0.0)
        if self.latched and self.overload is not None:
            lim = self.overload.latched_limit_nm
            tau_m = max(-lim, min(lim, tau_m))
        elif self.overload is not None and abs(tau_m) >= self.overload.threshold_nm:
            return False
        if abs(tau_m + tau_ext) > self.params.stiction_nm:
            return False
        self.tau_motor_nm, self.tau_wall_nm = tau_m, wall
        self.peak_tau_motor_nm = max(self.peak_tau_motor_nm, abs(tau_m))
        self._over_s = 0.0
        self._rest = (drive, self.overload, self.params, q, self.link_rad, self.latched, tau_m, wall)
        return True


# Scenarios live in their own module; re-exported here (they build on the classes above).
from .scenarios import Scenario, make_plant  # noqa: E402
