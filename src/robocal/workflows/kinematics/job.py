"""Kinematic identification end to end: URDF + measurements → fit → report, corrected URDF; and simulation.

``identify`` reads the chain from a URDF and a measurement CSV (:mod:`robocal.formats.kinematic_data`), checks
every pose against the joint limits, holds out a validation share, analyses identifiability, fits the base set
(:mod:`robocal.workflows.kinematics.fit`), optionally compares with a DH-like fit, and only then writes the
corrected URDF (joint origins with the zero offsets folded in; nothing else in the file changes) and a JSON
report, atomically. ``simulate`` (:mod:`robocal.workflows.kinematics.sim`) produces a session from a simulated
SO-101 or Koch with hidden errors; ``plan`` (:mod:`robocal.workflows.kinematics.plan`) chooses the poses.
"""

from __future__ import annotations

import math
import os
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from ...core.arrays import FloatArray
from ...core.chain import SerialChain
from ...core.jointmap import RobotCalibration
from ...core.kinematic_errors import ErrorModel
from ...core.kinematic_problem import (
    Measurements,
    Problem,
    dh_like_constraints,
    free_indices,
)
from ...errors import UsageError
from ...formats.kinematic_data import read_measurements
from ...formats.urdf import UrdfDocument
from ...formats.urdf_chain import chain_from_urdf
from . import gates as gates
from . import plausibility as plaus
from . import report as kr
from .export import check_export_paths, check_ur_chain
from .fit import (
    FitResult,
    PriorSigmas,
    fit,
    predicted_error_m,
    validation_errors,
)
from .request import DEFAULT_VALIDATE_FRACTION, POINT_FRAMES, IdentifyOutputs, IdentifyRequest

__all__ = [
    "DEFAULT_VALIDATE_FRACTION",
    "POINT_FRAMES",
    "DhComparison",
    "IdentifyOutputs",
    "IdentifyRequest",
    "IdentifyResult",
    "PriorSigmas",
    "as_prior",
    "identify",
    "identify_joint_map",
    "tool_frame",
]


@dataclass(frozen=True, eq=False)
class DhComparison:
    """A DH-like fit of the same data (biased when consecutive axes are parallel).

    Attributes:
        held_joints: Joints whose tilt towards the parallel previous axis DH cannot express.
        train_errors_m: Per-pose errors on the fitted poses.
        validation_errors_m: Per-pose errors on the held-out poses.
    """

    held_joints: tuple[str, ...]
    train_errors_m: FloatArray
    validation_errors_m: FloatArray


@dataclass(frozen=True, eq=False)
class IdentifyResult:
    """What ``identify`` found and wrote.

    Attributes:
        fit: The fit.
        validation: Held-out measurements (may have no poses).
        validation_errors_m: Per-pose errors of the corrected model on them.
        nominal_validation_errors_m: The same for the nominal model.
        dh: The DH-like comparison, when asked for.
        chain: The corrected chain (offsets folded into the origins).
        urdf_out: Corrected URDF written, or None.
        report_out: JSON report written, or None.
        report: The report as a dict (what the JSON holds).
        warnings: Things the user should know.
    """

    fit: FitResult
    validation: Measurements
    validation_errors_m: FloatArray
    nominal_validation_errors_m: FloatArray
    dh: DhComparison | None
    chain: SerialChain
    urdf_out: Path | None
    report_out: Path | None
    report: dict[str, Any]
    warnings: tuple[str, ...] = field(default_factory=tuple)


def _stats_mm(errors: FloatArray) -> dict[str, float] | None:
    return kr.error_stats(errors, 1e3)


def _noise_mm(result: FitResult) -> float | None:
    """Marker noise per axis (mm) estimated from the fit's residuals: ``sqrt(Σ r² / (3 N − rank))``; None if no dof."""
    dof = 3 * result.train_errors_m.size - result.identifiability.rank
    return None if dof <= 0 else float(np.sqrt(np.sum(result.train_errors_m**2) / dof) * 1e3)


PREDICTION_POSES = 2000
"""Random poses inside the limits the report's predicted error is averaged over (seeded, the same every run)."""


def _predicted_mm(result: FitResult, chain: SerialChain) -> float | None:
    """The tool point's predicted RMS error (mm) at random poses from the fit's covariance; None if unknown."""
    from .plan import sampling_bounds  # kinematic_plan imports this module

    lo, up = sampling_bounds(chain, 0.0)
    q = np.random.default_rng(0).uniform(lo, up, (PREDICTION_POSES, chain.n_q))
    value = predicted_error_m(result, q)
    return None if not math.isfinite(value) else value * 1e3


def _kabsch(p_from: FloatArray, p_to: FloatArray) -> FloatArray:
    """Rigid transform ``T`` with ``T · p_from ≈ p_to`` (least squares), ``(4, 4)``."""
    a0, b0 = p_from.mean(axis=0), p_to.mean(axis=0)
    H = (p_from - a0).T @ (p_to - b0)
    U, _, Vt = np.linalg.svd(H)
    d = np.sign(np.linalg.det(Vt.T @ U.T))
    R = Vt.T @ np.diag([1.0, 1.0, d]) @ U.T
    T = np.eye(4)
    T[:3, :3] = R
    T[:3, 3] = b0 - R @ a0
    return T


def tool_frame(tool_xyz_m: Sequence[float]) -> FloatArray:
    """``T_tip_tool`` ``(4, 4)`` for a tool point in the tip link's frame (m); UsageError unless 3 finite numbers."""
    t = [float(v) for v in tool_xyz_m]
    if len(t) != 3 or not all(math.isfinite(v) for v in t):
        raise UsageError(f"--tool-xyz needs three finite numbers (m), got {list(tool_xyz_m)}")
    T = np.eye(4)
    T[:3, 3] = t
    return T


def identify_joint_map(
    joint_map: Path | None,
    robot: str | None,
    robot_id: str | None,
    calibration_dir: Path | None,
    calibration_file: Path | None,
) -> tuple[RobotCalibration | None, dict[str, int]]:
    """The joint map given to ``identify`` (``--joint-map`` file, or a LeRobot arm's calibration), with ids.

    Raises:
        UsageError: Both a joint map and a LeRobot arm, or ``robot_id`` / ``calibration_file`` without ``robot``.
    """
    if joint_map is not None:
        if robot is not None or robot_id is not None or calibration_file is not None:
            raise UsageError("give --joint-map or --robot with --id/--calibration-file, not both")
        from ...formats import read_calibration

        cf = read_calibration(joint_map)
        return cf.calibration, dict(cf.ids)
    if robot is None:
        if robot_id is not None or calibration_file is not None:
            raise UsageError("--id and --calibration-file need --robot")
        return None, {}
    from ..lerobot import robot_spec
    from .record import lerobot_joint_map

    spec = robot_spec(robot)
    return lerobot_joint_map(spec, robot_id, calibration_dir, calibration_file), {
        m.name: m.motor_id for m in spec.motors
    }


def _validation_session(
    path: str | os.PathLike[str],
    kind: str,
    chain: SerialChain,
    labels: Sequence[str],
    gauge_distance_m: float | None,
) -> Measurements:
    """A separate session of held-out poses, its touch groups numbered as in the fitted session.

    Raises:
        CalibError: The file is unreadable or malformed, a pose is outside the limits, or it touches a point the
            fitted session never touched.
    """
    val, val_labels = read_measurements(path, kind, chain.joint_names, distance_m=gauge_distance_m, held_out=True)
    chain.check_q(val.q_rad, what=f"{path}: pose")
    if kind != "touch":
        return val
    unknown = [label for label in val_labels if label not in labels]
    if unknown:
        raise UsageError(
            f"{path}: touches point(s) {', '.join(unknown)} that the fitted session never touched "
            f"(it touched {', '.join(labels)})"
        )
    assert val.group is not None
    renumber = np.array([list(labels).index(label) for label in val_labels], dtype=np.int64)
    return Measurements("touch", val.q_rad, group=renumber[val.group])


def as_prior(prior: bool | PriorSigmas) -> PriorSigmas | None:
    """``--prior`` as given: a :class:`PriorSigmas`, True for the default tolerance, False for none."""
    return prior if isinstance(prior, PriorSigmas) else (PriorSigmas() if prior else None)


def identify(request: IdentifyRequest) -> IdentifyResult:
    """Identify a URDF chain's geometric errors from a measurement session.

    Args:
        request: What to identify and what to write (checked when it was built).

    Returns:
        The :class:`IdentifyResult`; files are written only after everything succeeded.

    Raises:
        CalibError: Unreadable or malformed files, a pose outside the limits, NaN, too few distinct poses, poses
            that leave parameters unidentifiable that the model can identify, implausible corrections.
    """
    r, o = request, request.outputs
    urdf, data, kind, frame, validate_data = r.urdf, r.data, r.kind, r.frame, r.validate_data
    inputs = {"--urdf": urdf, "--data": data, "--validate-data": validate_data}
    paths = check_export_paths(o.out, o.report, o.joint_map_out, o.ur_yaml, o.joint_map, o.ur_hash, inputs)
    doc = UrdfDocument.load(urdf)
    chain = chain_from_urdf(doc.model(), r.base_link, r.tip_link)
    if o.ur_yaml is not None:
        check_ur_chain(chain)  # before the data are judged: an option that cannot work is the first thing to say
    measurements, labels = read_measurements(data, kind, chain.joint_names, distance_m=r.gauge_distance_m)
    chain.check_q(measurements.q_rad, what=f"{data}: pose")
    model = ErrorModel(chain, T_tip_tool=tool_frame(r.tool_xyz_m))
    warnings: list[str] = []
    if kind == "touch":
        assert measurements.group is not None
        once = [label for g, label in enumerate(labels) if int(np.sum(measurements.group == g)) == 1]
        warnings += [
            f"point {label} is touched once: one contact says nothing (the point's position is an unknown too); "
            "touch each point from 3 or more configurations"
            for label in once
        ]
    if frame == "tracker":
        assert measurements.p_world_m is not None
        distinct = measurements.subset(gates.pose_cells(measurements, chain, r.ticks_per_turn, source=str(data)).kept)
        assert distinct.p_world_m is not None
        T0 = _kabsch(model.points(distinct.q_rad), distinct.p_world_m)
        model = ErrorModel(chain, T_world_base=T0, T_tip_tool=model.T_tip_tool)
    free = free_indices(model, [] if frame == "tracker" else ["base"])

    def problem_of(poses: Measurements) -> Problem:
        return Problem(model, poses, free, np.zeros(model.n_params))

    held_out = gates.HeldOut(
        DEFAULT_VALIDATE_FRACTION if r.validate_fraction is None else r.validate_fraction,
        r.seed,
        None if validate_data is None
        else _validation_session(validate_data, kind, chain, labels, r.gauge_distance_m),
        None if validate_data is None else str(validate_data),
    )  # fmt: skip
    gated = gates.sessions(
        measurements, problem_of, chain, source=str(data), held_out=held_out, ticks_per_turn=r.ticks_per_turn,
        check=lambda poses: plaus.check_session(model, poses, frame=frame, source=str(data)),
    )  # fmt: skip
    warnings += gated.warnings
    train, val = gated.train, gated.validation
    problem = problem_of(train)
    prior_s = as_prior(r.prior)
    result = fit(problem, huber_m=r.huber_m, prior=prior_s)
    plaus.check_corrections(result, model, max_mm=r.max_correction_mm, max_deg=r.max_correction_deg)
    if not result.success:
        warnings.append("the optimiser stopped before converging; check the data for gross errors")
    residual, residual_report = plaus.residual_warnings(result, gated.train_rows, noise_m=r.noise_m, source=str(data))
    warnings += residual
    val_err = validation_errors(result, val) if val.n_poses else np.zeros(0)
    nominal_x = np.zeros(model.n_params)
    val_nom = np.zeros(0)
    if val.n_poses:
        val_nom = (
            validation_errors(result, val, nominal_x) if kind == "points" else np.full(val.n_poses, np.nan)
        )
    dh_cmp = None
    if r.dh:
        C, held = dh_like_constraints(problem)
        dh_fit = fit(problem, huber_m=r.huber_m, prior=prior_s, constraints=C)
        dh_cmp = DhComparison(
            held, dh_fit.train_errors_m, validation_errors(dh_fit, val) if val.n_poses else np.zeros(0)
        )
    corrected, T_world_base, T_tip_tool = model.corrected(result.x)
    ident = result.identifiability
    warnings += kr.condition_warnings(
        result,
        "spread the poses over the joint ranges (robocal kinematics plan chooses a good set) or record more of them",
    )
    for u in ident.unidentifiable:
        if u.reason.startswith("the marker is on"):
            warnings.append(f"{u.name}: {u.reason}")
    units = [model.parameters[free[i]].unit if i < len(free) else "m" for i in range(len(problem.names))]
    rep: dict[str, Any] = {
        "tool": "robocal kinematics identify",
        "urdf": str(urdf),
        "data": str(data),
        "kind": kind,
        "frame": frame,
        "chain": kr.chain_summary(chain),
        "poses": {"fit": train.n_poses, "validation": val.n_poses},
        "validation_data": None if validate_data is None else str(validate_data),
        **kr.fit_summary(result, len(problem.names), kr.prior_summary(prior_s, noise=True)),
        "errors_mm": {
            "fit": {
                "nominal": _stats_mm(result.nominal_train_errors_m),
                "corrected": _stats_mm(result.train_errors_m),
            },
            "validation": {
                "nominal": _stats_mm(val_nom) if kind == "points" else None,
                "corrected": _stats_mm(val_err),
            },
            "noise_per_axis": _noise_mm(result) if kind == "points" else None,
            # touch data leaves the overall size nominal: its covariance cannot say how far off that is
            "predicted_rms": None if kind == "touch" else _predicted_mm(result, chain),
        },
        "parameters": kr.parameter_rows(result, problem.names, units),
        **kr.model_summary(result, model, corrected),
        "tool_xyz_m": [float(v) for v in T_tip_tool[:3, 3]],
        "T_world_base": T_world_base.tolist(),
        "contact_groups": {
            label: [float(v) for v in p]
            for label, p in zip(labels, problem.points_of(result.theta), strict=False)
        },
        "dh_like": None
        if dh_cmp is None
        else {
            "held_joints": list(dh_cmp.held_joints),
            "errors_mm": {
                "fit": _stats_mm(dh_cmp.train_errors_m),
                "validation": _stats_mm(dh_cmp.validation_errors_m),
            },
            "note": "DH cannot tilt an axis towards a parallel neighbour: this is a floor, not noise",
        },
        "plausibility": {
            **gated.report,
            **residual_report,
            "max_correction": {"mm": r.max_correction_mm, "deg": r.max_correction_deg},
        },
        "warnings": warnings,
    }
    written_urdf, written_report = kr.write_identify_files(
        doc, chain, model, result, paths, rep, warnings, o
    )  # fmt: skip
    return IdentifyResult(
        fit=result,
        validation=val,
        validation_errors_m=val_err,
        nominal_validation_errors_m=val_nom,
        dh=dh_cmp,
        chain=corrected,
        urdf_out=written_urdf,
        report_out=written_report,
        report=rep,
        warnings=tuple(warnings),
    )
