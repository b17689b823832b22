"""Simulated measurement sessions on shipped robots (SO-101, Koch) with hidden geometric errors.

``simulate`` writes the nominal URDF, a session CSV and ``truth.json`` (the hidden errors) into a folder, so that
``robocal kinematics identify`` and ``robocal demo --identify`` run end to end without a robot.
"""

from __future__ import annotations

import json
import math
import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ...backends.sim.kinematic_arm import (
    SIM_ROBOTS,
    SimRobot,
    SimulatedKinematicArm,
    hidden_errors,
    shipped_urdf,
)
from ...core.arrays import FloatArray
from ...core.kinematic_errors import ErrorModel
from ...core.kinematic_problem import Measurements, check_kind, plan_poses
from ...errors import UsageError
from ...fileio import atomic_write_bytes, atomic_write_text
from ...formats.kinematic_data import measurements_to_csv
from ...formats.urdf import UrdfDocument
from ...formats.urdf_chain import chain_from_urdf
from .fit import check_seed
from .job import tool_frame

__all__ = [
    "SIM_ROBOTS",
    "SimRobot",
    "SimulationRequest",
    "SimulationResult",
    "check_ticks",
    "shipped_urdf",
    "sim_out_folder",
    "simulate",
]


def check_ticks(ticks_per_turn: int) -> int:
    """``--ticks`` as given: 0 (exact readings) or a positive count per turn; UsageError if negative."""
    if ticks_per_turn < 0:
        raise UsageError(f"--ticks must be 0 (exact readings) or a positive count per turn, got {ticks_per_turn}")
    return ticks_per_turn


def sim_out_folder(out_dir: str | os.PathLike[str]) -> Path:
    """``--out`` of a simulation, checked: a folder, or a new one in an existing folder (made when writing).

    Raises:
        UsageError: ``--out`` is a file, or its parent folder does not exist.
    """
    folder = Path(out_dir)
    if folder.is_dir() or (not folder.exists() and folder.parent.is_dir()):
        return folder
    if folder.exists():
        raise UsageError(f"--out {folder}: is a file; give a folder")
    raise UsageError(f"--out {folder}: folder {folder.parent} does not exist")


@dataclass(frozen=True, eq=False)
class SimulationResult:
    """Files written by :func:`simulate` and the hidden truth.

    Attributes:
        urdf: Nominal URDF copied into the folder.
        data: Measurement CSV.
        truth: JSON with the hidden parameters.
        tip_link: Link the marker is on.
        tool_xyz_m: Nominal marker position in ``tip_link``.
        arm: The simulated arm (hidden errors included).
        measurements: The session.
        validation: The separate held-out session ``<kind>_validation.csv``, or None.
        validation_measurements: Its measurements, or None.
        validation_truth_m: The true tool points of its poses ``(N, 3)``, m (points only), or None.
    """

    urdf: Path
    data: Path
    truth: Path
    tip_link: str
    tool_xyz_m: tuple[float, float, float]
    arm: SimulatedKinematicArm
    measurements: Measurements
    validation: Path | None = None
    validation_measurements: Measurements | None = None
    validation_truth_m: FloatArray | None = None


@dataclass(frozen=True)
class SimulationRequest:
    """A session to simulate on a shipped robot with hidden errors (``kinematics simulate``); checked when built.

    Attributes:
        robot: ``so101`` or ``koch``.
        out_dir: Folder (created if its parent exists).
        kind: ``points``, ``touch`` or ``gauge``.
        poses: Number of poses (touch: per contact point, 3 points; gauge: per socket).
        noise_m: Marker noise per axis (points only), m.
        seed: Seed of the hidden errors, the poses and the noise.
        on_axis: Put the marker on the last joint's axis (to see the identifiability report catch it).
        plan: Choose the poses by greedy I-optimal selection from 2000 random candidates (points only).
        gauge_distance_m: Socket distance of the simulated gauge.
        validation_poses: Also write ``<kind>_validation.csv``: this many random poses (touch: per point; gauge:
            per socket) held out from the fit (``identify --validate-data``); drawn after the session, so the
            session is the same with or without them.
        ticks_per_turn: Encoder ticks per turn the joint readings are rounded to (0: exact readings, the
            noise-free case).

    Raises:
        UsageError: An unknown kind, a pose, tick or validation count, noise or seed out of range.
    """

    robot: str
    out_dir: str | os.PathLike[str]
    kind: str = "points"
    poses: int = 50
    noise_m: float = 0.5e-3
    seed: int = 0
    on_axis: bool = False
    plan: bool = True
    gauge_distance_m: float = 0.05
    validation_poses: int = 0
    ticks_per_turn: int = 4096

    def __post_init__(self) -> None:
        check_kind(self.kind)
        if self.poses < 1:
            raise UsageError(f"--poses must be at least 1, got {self.poses}")
        check_ticks(self.ticks_per_turn)
        if self.validation_poses < 0:
            raise UsageError(f"--validation-poses must be 0 or more, got {self.validation_poses}")
        if not (math.isfinite(self.noise_m) and self.noise_m >= 0):
            raise UsageError(f"--noise-mm must be a non-negative number, got {self.noise_m * 1e3}")
        check_seed(self.seed)


def simulate(request: SimulationRequest) -> SimulationResult:
    """Simulate a session on a shipped robot with hidden errors.

    Writes ``<robot>.urdf`` (the nominal description), ``<kind>.csv`` and ``truth.json`` (and
    ``<kind>_validation.csv`` when asked) into the request's folder.

    Args:
        request: What to simulate (checked when it was built).

    Returns:
        The :class:`SimulationResult`.

    Raises:
        UsageError: An unknown robot, ``out_dir`` a file or in a missing folder.
    """
    r = request
    robot, kind, poses, noise_m, seed = r.robot, r.kind, r.poses, r.noise_m, r.seed
    gauge_distance_m, validation_poses = r.gauge_distance_m, r.validation_poses
    folder = sim_out_folder(r.out_dir)
    spec = SIM_ROBOTS.get(robot)
    src = shipped_urdf(robot)
    assert spec is not None
    urdf_bytes = src.read_bytes()
    doc = UrdfDocument.from_bytes(urdf_bytes, str(src))
    chain = chain_from_urdf(doc.model(), tip_link=spec.tip_link)
    marker = spec.marker_on_axis_m if r.on_axis else spec.marker_off_axis_m
    model = ErrorModel(chain, T_tip_tool=tool_frame(marker))
    rng = np.random.default_rng(seed)
    arm = SimulatedKinematicArm(model, hidden_errors(model, rng), ticks_per_turn=r.ticks_per_turn)
    labels: tuple[str, ...] = ()
    c = np.asarray(spec.gauge_centre_m)
    targets = np.stack([c, c + np.array([0.0, 0.06, 0.0]), c + np.array([-0.05, 0.0, 0.04])])
    if kind == "points":
        if r.plan:
            cand = arm.sample_q(2000, rng)
            q = cand[plan_poses(model, cand, poses, criterion="I")] if poses <= 2000 else arm.sample_q(poses, rng)
        else:
            q = arm.sample_q(poses, rng)
        truth = arm.true_points(q)
        data = Measurements("points", arm.read(q), truth + rng.normal(0.0, noise_m, truth.shape))
    elif kind == "touch":
        data = arm.touch(targets, poses, rng)
        labels = ("P1", "P2", "P3")
    else:
        data = arm.gauge(spec.gauge_centre_m, gauge_distance_m, poses, rng)
    val_data: Measurements | None = None
    val_truth: FloatArray | None = None
    if validation_poses:
        if kind == "points":
            val_data, val_truth = arm.measure_points(validation_poses, noise_m, rng)
        else:
            val_data = (
                arm.touch(targets, validation_poses, rng)
                if kind == "touch"
                else arm.gauge(spec.gauge_centre_m, gauge_distance_m, validation_poses, rng)
            )
    truth_doc = {
        "robot": robot,
        "seed": seed,
        "tip_link": spec.tip_link,
        "tool_xyz_m": list(marker),
        "noise_m": noise_m if kind == "points" else 0.0,
        "ticks_per_turn": arm.ticks_per_turn,
        "hidden_parameters": {n: float(v) for n, v in zip(model.names, arm.x_true, strict=True)},
    }
    folder.mkdir(exist_ok=True)  # only now: nothing is made when the simulation fails
    urdf_path = atomic_write_bytes(folder / f"{robot}.urdf", urdf_bytes)
    data_path = atomic_write_text(
        folder / f"{kind}.csv", measurements_to_csv(data, chain.joint_names, labels)
    )
    val_path = (
        None
        if val_data is None
        else atomic_write_text(
            folder / f"{kind}_validation.csv", measurements_to_csv(val_data, chain.joint_names, labels)
        )
    )
    truth_path = atomic_write_text(folder / "truth.json", json.dumps(truth_doc, indent=2) + "\n")
    return SimulationResult(
        urdf_path, data_path, truth_path, spec.tip_link, marker, arm, data, val_path, val_data, val_truth
    )
