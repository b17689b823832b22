"""Pose planning for kinematic identification: which configurations to measure (``robocal kinematics plan``).

Candidates are drawn uniformly inside the URDF's joint limits (or read from a joint table of poses known to be
reachable); :func:`robocal.core.kinematic_problem.plan_poses` picks the poses greedily, I-optimal by default
(the smallest average prediction variance of the tool point over the candidates), optionally Bayesian with the
URDF's tolerance as a prior. The plan is a CSV (``pose`` + one column per joint, radians) the user drives the
arm to, and that ``robocal kinematics record --plan`` shows pose by pose.
"""

from __future__ import annotations

import math
import os
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ...core.arrays import FloatArray, IntArray
from ...core.chain import SerialChain
from ...core.identifiability import Identifiability
from ...core.kinematic_errors import ErrorModel
from ...core.kinematic_problem import (
    PLAN_CRITERIA,
    Measurements,
    Problem,
    analyse,
    check_kind,
    free_indices,
    plan_poses,
)
from ...core.pose_plan import plan_contact_poses, reach_point
from ...errors import UsageError, check_choice
from ...fileio import atomic_write_text, check_output_path
from ...formats.kinematic_data import read_joint_table, session_csv
from ...formats.urdf import UrdfDocument
from ...formats.urdf_chain import chain_from_urdf
from .fit import PriorSigmas, check_seed, prediction_rms_m
from .job import POINT_FRAMES, as_prior, tool_frame

__all__ = ["PlanRequest", "PlanResult", "plan"]


@dataclass(frozen=True, eq=False)
class PlanResult:
    """Poses chosen for a measurement session.

    Attributes:
        q_rad: ``(N, n_q)`` joint targets, rad (m for prismatic joints).
        joint_names: Column order.
        identifiability: What point measurements at these poses will identify.
        out: CSV written.
        criterion: ``I`` or ``D``.
        candidates: How many candidate configurations the poses were chosen from.
        prediction_sigma_m: Predicted one-σ error of the tool point averaged over the candidates after
            identification from these poses (marker noise ``noise_m``; linearised at nominal), m.
        validation_out: The plan of held-out poses written beside ``out``, or None.
    """

    q_rad: FloatArray
    joint_names: tuple[str, ...]
    identifiability: Identifiability
    out: Path
    criterion: str = "I"
    candidates: int = 0
    prediction_sigma_m: float = math.nan
    validation_out: Path | None = None


@dataclass(frozen=True)
class PlanRequest:
    """Choose ``poses`` configurations inside the joint limits that best identify the chain (``kinematics plan``).

    ``I`` (default): each pose lowers most the tool point's prediction variance averaged over the candidates
    (I-optimal); ``D``: each raises most ``det(JᵀJ)`` (O1). With ``prior`` the I-optimal plan is Bayesian: it
    counts the URDF tolerance as known already. The options are checked when the request is built.

    Attributes:
        urdf: Expanded URDF.
        out: CSV to write (atomically; nothing is written on an error).
        poses: How many poses.
        base_link: First link of the chain (default: the URDF root).
        tip_link: Link the marker is on (default: the only leaf).
        tool_xyz_m: Nominal marker position in the tip link, m.
        kind: ``points`` (free poses), ``touch`` or ``gauge`` (poses that put the tool on ``touch_points_m``).
        frame: ``base`` or ``tracker`` (the base pose is then estimated too).
        criterion: ``I`` or ``D`` (either case).
        prior: Plan for a fit with this prior (True: the default tolerance); ``I`` only.
        noise_m: The tracker's noise per axis, m (weighs the data against the prior; the predicted σ).
        candidates: Random candidates drawn uniformly inside the limits (minus ``margin_rad``).
        candidates_file: Take the candidates from this joint table instead (e.g. poses known to be reachable
            without collision); each is checked against the limits.
        margin_rad: Distance kept from the joint limits by the random candidates.
        seed: Seed of the random candidates.
        touch_points_m: ``touch``: the fixed points (one or more), ``gauge``: sockets A and B; nominal positions
            in the chain's base frame, m. Candidates are the configurations of the nominal arm that reach them
            (damped least squares from ``candidates`` random starts per point).
        validation_poses: Also write ``<out stem>_validation<suffix>``: this many candidates the plan did not
            choose, at random (touch, gauge: configurations that reach one of the points), to record as a
            separate session for ``identify --validate-data`` so that every planned pose is fitted.

    Raises:
        UsageError: An unknown criterion, kind or frame, an option of another kind, a prior with ``D``, a noise,
            pose count, validation count or seed out of range.
    """

    urdf: str | os.PathLike[str]
    out: str | os.PathLike[str]
    poses: int = 50
    base_link: str | None = None
    tip_link: str | None = None
    tool_xyz_m: Sequence[float] = (0.0, 0.0, 0.0)
    kind: str = "points"
    frame: str = "base"
    criterion: str = "I"
    prior: bool | PriorSigmas = False
    noise_m: float = 0.5e-3
    candidates: int = 2000
    candidates_file: str | os.PathLike[str] | None = None
    margin_rad: float = 0.05
    seed: int = 0
    touch_points_m: Sequence[Sequence[float]] = ()
    validation_poses: int = 0

    def __post_init__(self) -> None:
        criterion, kind, touch_points_m = self.criterion, self.kind, self.touch_points_m
        crit = criterion.upper()
        if crit not in PLAN_CRITERIA:
            raise UsageError(f"--criterion {criterion!r}; valid: {', '.join(c.lower() for c in PLAN_CRITERIA)}")
        check_kind(kind)
        if kind == "points" and touch_points_m:
            raise UsageError("--touch-points applies to --kind touch or gauge")
        if kind != "points":
            if crit != "I" or self.prior or self.frame != "base" or self.candidates_file is not None:
                raise UsageError(
                    f"--kind {kind} plans are I-optimal in the base frame from random starts: --criterion d, "
                    "--prior, --frame tracker and --candidates-file apply to --kind points"
                )
            need = "two points (sockets A and B)" if kind == "gauge" else "one or more points"
            if (kind == "gauge" and len(touch_points_m) != 2) or not touch_points_m:
                raise UsageError(f"--kind {kind} needs --touch-points with {need}, x,y,z in metres each")
        check_choice("--frame", self.frame, POINT_FRAMES)
        if not (math.isfinite(self.noise_m) and self.noise_m > 0):
            raise UsageError(f"--noise-mm must be a positive number, got {self.noise_m * 1e3}")
        if as_prior(self.prior) is not None and crit != "I":
            raise UsageError("a prior applies to the I-optimal plan (--criterion i)")
        if self.poses < 1:
            raise UsageError(f"--poses must be at least 1, got {self.poses}")
        if self.validation_poses < 0:
            raise UsageError(f"--validation-poses must be 0 or more, got {self.validation_poses}")
        check_seed(self.seed)


def plan(request: PlanRequest) -> PlanResult:
    """Choose the poses of ``request`` greedily and write them as a CSV.

    The CSV has a ``pose`` column and one column per joint (radians), ready to be filled with ``x,y,z`` as the
    poses are measured.

    Args:
        request: What to plan (checked when it was built).

    Returns:
        The :class:`PlanResult`.

    Raises:
        CalibError: Too few poses for the identifiable parameters, a candidate outside the limits or not a
            number, an unreadable URDF or candidates file, an output in a missing folder.
    """
    r = request
    crit, kind, frame, poses, noise_m = r.criterion.upper(), r.kind, r.frame, r.poses, r.noise_m
    candidates, candidates_file, margin_rad, seed = r.candidates, r.candidates_file, r.margin_rad, r.seed
    prior_s = as_prior(r.prior)
    validation_poses = r.validation_poses
    inputs = {"--urdf": r.urdf, "--candidates-file": candidates_file}
    out_path = check_output_path(r.out, "--out", inputs=inputs)
    val_path = validation_path(out_path, inputs) if validation_poses else None
    chain = chain_from_urdf(UrdfDocument.load(r.urdf).model(), r.base_link, r.tip_link)
    model = ErrorModel(chain, T_tip_tool=tool_frame(r.tool_xyz_m))
    if kind != "points":
        return _plan_contacts(
            model, out_path, kind, [np.asarray(p, dtype=np.float64) for p in r.touch_points_m], poses,
            max(candidates, 1), margin_rad, seed, (val_path, validation_poses),
        )  # fmt: skip
    if candidates_file is not None:
        cand = chain.check_q(
            read_joint_table(candidates_file, chain.joint_names), what=f"{candidates_file}: pose"
        )
    else:
        if candidates < 1:
            raise UsageError(f"--candidates must be at least 1, got {candidates}")
        lo, up = sampling_bounds(chain, margin_rad)
        cand = np.random.default_rng(seed).uniform(lo, up, (candidates, chain.n_q))
    if cand.shape[0] < poses:
        raise UsageError(f"--poses {poses}: only {cand.shape[0]} candidate poses to choose from")
    exclude = [] if frame == "tracker" else ["base"]
    everything = Problem(
        model,
        Measurements("points", cand, model.points(cand)),
        free_indices(model, exclude),
        np.zeros(model.n_params),
    )
    rank = analyse(everything).rank
    if 3 * poses <= rank:
        raise UsageError(
            f"too few poses: {poses} poses give {3 * poses} equations, not more than the {rank} parameters the "
            f"candidates can identify; plan at least {rank // 3 + 2} poses (20 or more for a useful result)"
        )
    sig = None if prior_s is None else prior_s.model_sigmas(model)
    idx = plan_poses(
        model, cand, poses, exclude_groups=exclude, criterion=crit, prior_sigma=sig, noise_m=noise_m
    )
    q = cand[idx]
    val_idx = _held_out(cand.shape[0], idx, validation_poses, seed)
    problem = Problem(
        model, Measurements("points", q, model.points(q)), everything.free, np.zeros(model.n_params)
    )
    ident = analyse(problem)
    written = atomic_write_text(out_path, session_csv(q, chain.joint_names, {}))
    val_written = None
    if val_path is not None:
        val_written = atomic_write_text(val_path, session_csv(cand[val_idx], chain.joint_names, {}))
    return PlanResult(
        q, chain.joint_names, ident, written, crit, int(cand.shape[0]),
        _prediction_sigma(everything, problem, ident, noise_m, sig), val_written,
    )  # fmt: skip


def validation_path(out_path: Path, inputs: Mapping[str, str | os.PathLike[str] | None] | None = None) -> Path:
    """Where a plan's held-out poses go: ``poses.csv`` → ``poses_validation.csv`` (checked writable, not an input)."""
    path = out_path.with_name(f"{out_path.stem}_validation{out_path.suffix}")
    return check_output_path(path, "--out", inputs=inputs)


def _held_out(n_candidates: int, chosen: IntArray, n: int, seed: int) -> IntArray:
    """``n`` random candidate indices the plan did not choose (a seeded draw of their own).

    Raises:
        UsageError: Fewer unchosen candidates than ``n``.
    """
    rest = np.setdiff1d(np.arange(n_candidates), np.asarray(chosen, dtype=np.int64))
    if rest.size < n:
        raise UsageError(
            f"--validation-poses {n}: only {rest.size} candidate poses are left beside the plan; draw more "
            "candidates (--candidates) or hold out fewer"
        )
    return np.sort(np.random.default_rng([seed, 1]).choice(rest, n, replace=False)).astype(np.int64)


def sampling_bounds(chain: SerialChain, margin_rad: float) -> tuple[FloatArray, FloatArray]:
    """``(n_q,)`` lower and upper joint bounds (rad) to draw candidate poses in.

    The URDF limits (±π where a joint has none), shrunk by ``margin_rad`` on each side.

    Raises:
        UsageError: A joint's range is narrower than twice the margin.
    """
    lo, up = chain.limits()
    lo = np.where(np.isfinite(lo), lo, -math.pi) + margin_rad
    up = np.where(np.isfinite(up), up, math.pi) - margin_rad
    if np.any(lo > up):
        bad = chain.joint_names[int(np.argmax(lo > up))]
        raise UsageError(f"joint {bad}: its range is narrower than twice the {margin_rad} rad margin")
    return np.asarray(lo, dtype=np.float64), np.asarray(up, dtype=np.float64)


def _plan_contacts(
    model: ErrorModel,
    out_path: Path,
    kind: str,
    points: list[FloatArray],
    poses: int,
    starts: int,
    margin_rad: float,
    seed: int,
    validation: tuple[Path | None, int],
) -> PlanResult:
    """A touch or gauge plan: reachable configurations per point, then the I-optimal greedy choice."""
    chain = model.chain
    rng = np.random.default_rng(seed)
    lo, up = sampling_bounds(chain, margin_rad)
    qs, groups = [], []
    for g, point in enumerate(points):
        if point.shape != (3,) or not np.all(np.isfinite(point)):
            raise UsageError(
                f"--touch-points: point {g + 1} is {point.tolist()}; expected three finite numbers"
            )
        found = reach_point(
            model, point, rng.uniform(lo, up, (starts, chain.n_q)), (lo, up), tolerance_m=1e-7
        )
        found = np.unique(np.round(found, 3), axis=0)  # distinct to about 0.06°
        if found.shape[0] < 3:
            raise UsageError(
                f"--touch-points: point {g + 1} {point.tolist()} m is reached by {found.shape[0]} configurations "
                "inside the joint limits (nominal URDF); put it where the arm reaches it in several ways"
            )
        qs.append(reach_point(model, point, found, (lo, up), tolerance_m=1e-9))
        groups += [g] * qs[-1].shape[0]
    cand = np.concatenate(qs)
    group = np.asarray(groups, dtype=np.int64)
    distance = float(np.linalg.norm(points[1] - points[0])) if kind == "gauge" else None
    if kind == "gauge" and not (distance is not None and distance > 0.0):
        raise UsageError("--touch-points: sockets A and B are the same point")
    free = free_indices(model, ["base"])
    everything = Problem(
        model, Measurements(kind, cand, group=group, distance_m=distance), free, np.zeros(model.n_params)
    )
    rank = analyse(everything).rank
    if 3 * poses <= rank:
        raise UsageError(
            f"too few poses: {poses} poses give {3 * poses} equations, not more than the {rank} unknowns the "
            f"candidates can identify; plan at least {rank // 3 + 2} poses (20 or more for a useful result)"
        )
    if cand.shape[0] < poses:
        raise UsageError(f"--poses {poses}: only {cand.shape[0]} reaching configurations to choose from")
    q_predict = rng.uniform(lo, up, (2000, chain.n_q))
    idx = plan_contact_poses(model, cand, group, poses, q_predict, kind=kind, distance_m=distance)
    missing = sorted(set(range(len(points))) - set(group[idx].tolist()))
    if missing:
        raise UsageError(
            f"the plan touches no point {', '.join(str(g + 1) for g in missing)}: plan more poses or fewer points"
        )
    q, g_sel = cand[idx], group[idx]
    val_path, n_val = validation
    val_idx = _held_out(cand.shape[0], idx, n_val, seed)
    ident = analyse(
        Problem(
            model, Measurements(kind, q, group=g_sel, distance_m=distance), free, np.zeros(model.n_params)
        )
    )
    column = "socket" if kind == "gauge" else "group"

    def labels(g: IntArray) -> list[str]:
        return [("A" if v == 0 else "B") if kind == "gauge" else f"P{v + 1}" for v in g.tolist()]

    written = atomic_write_text(out_path, session_csv(q, chain.joint_names, {column: labels(g_sel)}))
    val_written = None
    if val_path is not None:
        val_written = atomic_write_text(
            val_path, session_csv(cand[val_idx], chain.joint_names, {column: labels(group[val_idx])})
        )
    return PlanResult(
        q, chain.joint_names, ident, written, "I", int(cand.shape[0]), validation_out=val_written
    )  # fmt: skip


def _prediction_sigma(
    everything: Problem, problem: Problem, ident: Identifiability, noise_m: float, sig: FloatArray | None
) -> float:
    """RMS over the candidates of the tool point's predicted σ (m) after a fit from ``problem``'s poses."""
    _, J = problem.residuals_and_jacobian(problem.initial_theta())
    cols = list(ident.base)
    prior_info = np.zeros(len(cols))
    if sig is not None:
        s = sig[list(problem.free)]
        cols = sorted(set(cols) | {c for c in range(len(problem.free)) if math.isfinite(s[c])})
        prior_info = np.where(np.isfinite(s[cols]), s[cols] ** -2.0, 0.0)
    info = J[:, cols].T @ J[:, cols] / noise_m**2 + np.diag(prior_info)
    try:
        cov = np.linalg.inv(info)
    except np.linalg.LinAlgError:
        return math.nan
    return prediction_rms_m(everything, cols, cov)
