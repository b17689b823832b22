"""A simulated arm with hidden geometric errors, for kinematic identification tests and demos.

The true arm is the nominal :class:`~robocal.core.kinematic_errors.ErrorModel` with a hidden parameter vector:
origin translations ``N(0, 1 mm)``, origin tilts ``N(0, 0.5°)``, joint zero offsets ``N(0, 2°)``, tool translation
``N(0, 1 mm)`` by default. Joint readings are quantised like a 4096-tick encoder; the joint really sits at the
unquantised angle. Measurements: the tool point with Gaussian marker noise, touch contacts (the tip on fixed
points, configurations found by inverse kinematics on the true arm) and a two-socket gauge.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from importlib import resources
from pathlib import Path

import numpy as np
from numpy.typing import ArrayLike

from ...core.arrays import FloatArray
from ...core.kinematic_errors import ErrorModel
from ...core.kinematic_problem import Measurements
from ...core.pose_plan import reach_point
from ...errors import UsageError

__all__ = ["SIM_ROBOTS", "ErrorSigmas", "SimRobot", "SimulatedKinematicArm", "hidden_errors", "shipped_urdf"]


TICKS_PER_TURN = 4096


@dataclass(frozen=True)
class ErrorSigmas:
    """Standard deviations of the hidden errors.

    Attributes:
        origin_m: Origin translations (m).
        tilt_rad: Origin rotations (rad).
        offset_rad: Joint zero offsets (rad).
        tool_m: Tool translation (m).
    """

    origin_m: float = 1e-3
    tilt_rad: float = math.radians(0.5)
    offset_rad: float = math.radians(2.0)
    tool_m: float = 1e-3


def hidden_errors(
    model: ErrorModel, rng: np.random.Generator, sigmas: ErrorSigmas | None = None
) -> FloatArray:
    """A random parameter vector: the "true" arm's deviation from the nominal model (base and tool tilt zero)."""
    s = sigmas or ErrorSigmas()
    x = np.zeros(model.n_params)
    for i, p in enumerate(model.parameters):
        if p.group == "base" or (p.group == "tool" and p.unit == "rad"):
            continue
        if p.group == "tool":
            x[i] = rng.normal(0.0, s.tool_m)
        elif p.kind == "offset":
            x[i] = rng.normal(0.0, s.offset_rad)
        else:
            x[i] = rng.normal(0.0, s.origin_m if p.unit == "m" else s.tilt_rad)
    return x


@dataclass(frozen=True, eq=False)
class SimulatedKinematicArm:
    """The true arm behind a nominal model.

    Attributes:
        model: Nominal error model (the URDF and tool the user believes in).
        x_true: Hidden parameters of the real arm.
        ticks_per_turn: Encoder resolution of the joint readings (0 disables quantisation).
        margin_rad: Poses stay this far inside the joint limits.
    """

    model: ErrorModel
    x_true: FloatArray
    ticks_per_turn: int = TICKS_PER_TURN
    margin_rad: float = 0.05
    _limits: tuple[FloatArray, FloatArray] = field(init=False, repr=False)

    def __post_init__(self) -> None:
        lo, up = self.model.chain.limits()
        lo = np.where(np.isfinite(lo), lo, -math.pi) + self.margin_rad
        up = np.where(np.isfinite(up), up, math.pi) - self.margin_rad
        object.__setattr__(self, "_limits", (lo, up))

    def sample_q(self, n: int, rng: np.random.Generator) -> FloatArray:
        """``(n, n_q)`` true joint angles, uniform inside the limits."""
        lo, up = self._limits
        return rng.uniform(lo, up, (n, lo.size))

    def read(self, q_true: ArrayLike) -> FloatArray:
        """What the encoders report for true angles: rounded to whole ticks."""
        q = np.asarray(q_true, dtype=np.float64)
        if not self.ticks_per_turn:
            return np.array(q, dtype=np.float64)
        tick = 2.0 * math.pi / self.ticks_per_turn
        return np.asarray(np.round(q / tick) * tick, dtype=np.float64)

    def true_points(self, q_true: ArrayLike) -> FloatArray:
        """``(N, 3)`` true tool points for true joint angles."""
        return self.model.points(q_true, self.x_true)

    def measure_points(
        self, n: int, noise_m: float, rng: np.random.Generator
    ) -> tuple[Measurements, FloatArray]:
        """``n`` random poses measured by a tracker with isotropic Gaussian noise ``noise_m`` per axis.

        Returns:
            The measurements (quantised readings, noisy points) and the true points ``(n, 3)``.
        """
        q = self.sample_q(n, rng)
        truth = self.true_points(q)
        p = truth + rng.normal(0.0, noise_m, truth.shape)
        return Measurements("points", self.read(q), p), truth

    def _ik(self, target: FloatArray, q0: FloatArray, iters: int = 80) -> FloatArray:
        """Damped least-squares IK of the tool point on the true arm from many starts at once.

        Args:
            target: ``(3,)`` point, m.
            q0: ``(M, n_q)`` start configurations.
            iters: Iterations.

        Returns:
            ``(K, n_q)`` configurations inside the limits that reach the target within 1 nm.
        """
        return reach_point(self.model, target, q0, self._limits, x=self.x_true, iterations=iters)

    def touch(
        self,
        targets: ArrayLike,
        per_target: int,
        rng: np.random.Generator,
        *,
        kind: str = "touch",
        distance_m: float | None = None,
    ) -> Measurements:
        """Touch each target point from ``per_target`` different configurations.

        Args:
            targets: ``(G, 3)`` fixed points in the base frame (m), reachable by the true arm.
            per_target: Configurations per point.
            rng: Random generator (start configurations of the IK).
            kind: ``touch`` or ``gauge`` (the groups are then 0 = socket A, 1 = socket B).
            distance_m: The gauge's socket distance (``gauge`` only).

        Returns:
            Measurements with quantised readings and the group of each pose.
        """
        P = np.atleast_2d(np.asarray(targets, dtype=np.float64))
        qs: list[FloatArray] = []
        groups: list[int] = []
        for g, target in enumerate(P):
            found = 0
            for _ in range(4):
                for q in self._ik(target, self.sample_q(8 * per_target, rng)):
                    if found < per_target and all(
                        float(np.max(np.abs(q - o))) > 0.05 or g != h for o, h in zip(qs, groups, strict=True)
                    ):
                        qs.append(q)
                        groups.append(g)
                        found += 1
                if found == per_target:
                    break
            if found < per_target:
                raise UsageError(
                    f"simulated arm cannot touch point {target.tolist()} from {per_target} poses"
                )
        return Measurements(kind, self.read(np.array(qs)), group=np.array(groups), distance_m=distance_m)

    def gauge(
        self, centre: ArrayLike, distance_m: float, per_socket: int, rng: np.random.Generator
    ) -> Measurements:
        """A two-socket gauge centred at ``centre`` (m, base frame), sockets ``distance_m`` apart along x."""
        c = np.asarray(centre, dtype=np.float64)
        half = np.array([distance_m / 2.0, 0.0, 0.0])
        return self.touch(
            np.stack([c - half, c + half]), per_socket, rng, kind="gauge", distance_m=distance_m
        )


@dataclass(frozen=True)
class SimRobot:
    """A shipped robot description for simulations.

    Attributes:
        urdf: File name under ``robocal/data``.
        tip_link: Link carrying the marker.
        marker_off_axis_m: Marker position in the tip link, off the last joint's axis.
        marker_on_axis_m: The same marker moved onto the last joint's axis.
        gauge_centre_m: Where the simulated gauge sits, in the base frame.
    """

    urdf: str
    tip_link: str
    marker_off_axis_m: tuple[float, float, float]
    marker_on_axis_m: tuple[float, float, float]
    gauge_centre_m: tuple[float, float, float]


SIM_ROBOTS: dict[str, SimRobot] = {
    "so101": SimRobot(
        "so101_new_calib.urdf", "gripper_link", (0.0121, 0.0, -0.0981), (0.0, 0.0, -0.0981), (0.2, 0.0, 0.05)
    ),
    "koch": SimRobot(
        "koch.urdf", "gripper_static_1", (0.02, 0.0, -0.06), (0.0, 0.0, -0.06), (0.0, 0.15, 0.05)
    ),
}


def shipped_urdf(robot: str) -> Path:
    """Path of a shipped robot description (``so101``, ``koch``)."""
    if robot not in SIM_ROBOTS:
        raise UsageError(f"unknown simulated robot {robot!r}; valid: {', '.join(SIM_ROBOTS)}")
    return Path(str(resources.files("robocal") / "data" / SIM_ROBOTS[robot].urdf))
