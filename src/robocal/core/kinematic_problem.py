"""Identification problems: measurements, residuals, Jacobians and the identifiability report (pure numpy).

Three kinds of measurement share one error model (:class:`~robocal.core.kinematic_errors.ErrorModel`):

* ``points``: the tool point measured in a world frame (tracker, CMM). Residual ``p_model(q) − p_measured``.
  With ``frame="base"`` the world frame is the chain's base link; with ``frame="tracker"`` the base pose is
  estimated too (registration).
* ``touch``: the tool tip touched to fixed points from many configurations; poses with the same ``group`` touch
  the same unknown point ``P_g``. Residual ``p_model(q) − P_g``.
* ``gauge``: a ball in socket A (group 0) or socket B (group 1) of a printed gauge whose socket distance ``d`` is
  known; residuals as for touch plus ``√N·(‖P_A − P_B‖ − d)``, which fixes the scale touch data cannot see.

The unknowns ``θ`` are the free model parameters followed by the contact points. Identifiability names each
parameter the data cannot determine and says why (:func:`analyse`).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from ..errors import InvalidCalibrationError, ShapeMismatchError, UsageError, check_choice
from .arrays import FloatArray, IntArray
from .identifiability import (
    Explain,
    Identifiability,
    analyse_columns,
    common_reason,
    select_poses,
    select_poses_i_optimal,
    still_joints,
)
from .kinematic_errors import ErrorModel

__all__ = [
    "ALL_KINDS",
    "KINDS",
    "PLAN_CRITERIA",
    "Measurements",
    "Problem",
    "analyse",
    "check_kind",
    "dh_like_constraints",
    "free_indices",
    "marker_axis_distances",
    "plan_poses",
    "scale_direction",
]


KINDS: tuple[str, ...] = ("points", "touch", "gauge")
"""Tool-point sessions (a :class:`Measurements`): free points, touched points, a two-socket gauge."""
ALL_KINDS: tuple[str, ...] = (*KINDS, "tag")
"""Every ``--kind`` of the kinematics commands: the tool-point kinds and camera images of a tag (``tag``)."""


def check_kind(kind: str, valid: Sequence[str] = KINDS) -> str:
    """``kind`` if it is one of ``valid``; else the ``--kind`` error that lists them.

    Raises:
        UsageError: ``kind`` is not in ``valid``.
    """
    return check_choice("--kind", kind, valid)


@dataclass(frozen=True, eq=False)
class Measurements:
    """One measurement session.

    Attributes:
        kind: ``points``, ``touch`` or ``gauge``.
        q_rad: ``(N, n_q)`` joint readings (rad, or m for prismatic joints).
        p_world_m: ``(N, 3)`` measured tool points (``points`` only), metres.
        group: ``(N,)`` contact group per pose (``touch``: any integers; ``gauge``: 0 = socket A, 1 = B).
        distance_m: Socket distance of the gauge, metres (``gauge`` only).
    """

    kind: str
    q_rad: FloatArray
    p_world_m: FloatArray | None = None
    group: IntArray | None = None
    distance_m: float | None = None

    def __post_init__(self) -> None:
        if self.kind not in KINDS:
            raise UsageError(f"measurement kind {self.kind!r}; valid: {', '.join(KINDS)}")
        q = np.asarray(self.q_rad, dtype=np.float64)
        if q.ndim != 2:
            raise ShapeMismatchError(f"joint readings must be (N, n_q), got {q.shape}")
        object.__setattr__(self, "q_rad", q)
        if self.kind == "points":
            if self.p_world_m is None:
                raise UsageError("points measurements need the measured positions")
            p = np.asarray(self.p_world_m, dtype=np.float64)
            if p.shape != (q.shape[0], 3):
                raise ShapeMismatchError(f"measured points {p.shape}; expected ({q.shape[0]}, 3)")
            bad = np.flatnonzero(~np.all(np.isfinite(p), axis=1))
            if bad.size:
                raise InvalidCalibrationError(f"pose {bad[0] + 1}: measured point is {p[bad[0]].tolist()}")
            object.__setattr__(self, "p_world_m", p)
        else:
            if self.group is None:
                raise UsageError(f"{self.kind} measurements need a contact group per pose")
            g = np.asarray(self.group)
            if g.shape != (q.shape[0],):
                raise ShapeMismatchError(f"contact groups {g.shape}; expected ({q.shape[0]},)")
            object.__setattr__(self, "group", g.astype(np.int64))
            if self.kind == "gauge":
                if not set(np.unique(g).tolist()) <= {0, 1}:
                    raise UsageError("gauge sockets are 0 (A) and 1 (B), got " + str(sorted(set(g.tolist()))))
                d = self.distance_m
                if d is None or not math.isfinite(d) or d <= 0.0:
                    raise InvalidCalibrationError(f"gauge socket distance must be a positive length, got {d}")

    @property
    def n_poses(self) -> int:
        """Number of poses."""
        return int(self.q_rad.shape[0])

    def groups(self) -> tuple[int, ...]:
        """The distinct contact groups, sorted (empty for points)."""
        return () if self.group is None else tuple(int(v) for v in np.unique(self.group))

    def subset(self, rows: ArrayLike) -> Measurements:
        """The same session restricted to ``rows``."""
        r = np.asarray(rows)
        return Measurements(
            self.kind,
            self.q_rad[r],
            None if self.p_world_m is None else self.p_world_m[r],
            None if self.group is None else self.group[r],
            self.distance_m,
        )


def _priority(model: ErrorModel) -> FloatArray:
    """Preference for the base set: joint offsets, origin translations, tilts, tool, base."""
    rank = {"offset": 2, "x": 3, "y": 3, "z": 3, "rx": 4, "ry": 4, "rz": 4}
    out = []
    for p in model.parameters:
        if p.group == "base":
            out.append(1)  # when the base is free it is a registration: keep it
        elif p.group == "tool":
            out.append(5 if p.unit == "m" else 6)
        else:
            out.append(rank[p.kind])
    return np.asarray(out, dtype=np.float64)


@dataclass(frozen=True, eq=False)
class Problem:
    """Residuals and Jacobian of one measurement session over the free parameters.

    Attributes:
        model: The error model.
        data: The measurements.
        free: Indices of the model parameters that are estimated (the rest stay as in ``x_fixed``).
        x_fixed: ``(P,)`` values of all model parameters (the free ones are overwritten by ``θ``).
    """

    model: ErrorModel
    data: Measurements
    free: tuple[int, ...]
    x_fixed: FloatArray

    def __post_init__(self) -> None:
        # a held-out share may touch one socket; a fit needs both for the gauge's distance
        if self.data.kind == "gauge" and self.data.groups() != (0, 1):
            raise UsageError("gauge measurements need poses in both socket A and socket B")

    @property
    def group_ids(self) -> tuple[int, ...]:
        """Contact groups in the order their points appear in ``θ``."""
        return self.data.groups()

    @property
    def names(self) -> tuple[str, ...]:
        """Names of ``θ``: free model parameters, then ``point<g>.x/y/z`` (touch) or ``socketA/B.x/y/z``."""
        out = [self.model.names[i] for i in self.free]
        for g in self.group_ids:
            label = ("socketA" if g == 0 else "socketB") if self.data.kind == "gauge" else f"point{g}"
            out += [f"{label}.x", f"{label}.y", f"{label}.z"]
        return tuple(out)

    @property
    def n_theta(self) -> int:
        """Number of unknowns."""
        return len(self.free) + 3 * len(self.group_ids)

    def x_of(self, theta: ArrayLike) -> FloatArray:
        """The full model parameter vector for unknowns ``θ``."""
        x = np.array(self.x_fixed, dtype=np.float64)
        x[list(self.free)] = np.asarray(theta, dtype=np.float64)[: len(self.free)]
        return x

    def points_of(self, theta: ArrayLike) -> FloatArray:
        """``(G, 3)`` contact points in ``θ`` (empty for point data)."""
        t = np.asarray(theta, dtype=np.float64)
        return t[len(self.free) :].reshape(-1, 3)

    def initial_theta(self) -> FloatArray:
        """Free parameters from ``x_fixed`` and each contact point at its poses' mean nominal tool point."""
        t = [np.asarray(self.x_fixed)[list(self.free)]]
        if self.group_ids:
            p = self.model.points(self.data.q_rad, self.x_fixed)
            assert self.data.group is not None
            t += [p[self.data.group == g].mean(axis=0) for g in self.group_ids]
        return np.concatenate(t)

    def residuals_and_jacobian(self, theta: ArrayLike) -> tuple[FloatArray, FloatArray]:
        """Residual vector (m) and its Jacobian ``(R, n_theta)``."""
        p, Jp = self.model.point_jacobian(self.data.q_rad, self.x_of(theta))
        n = self.data.n_poses
        Jm = Jp[:, :, list(self.free)]
        if self.data.kind == "points":
            assert self.data.p_world_m is not None
            return (p - self.data.p_world_m).reshape(-1), Jm.reshape(3 * n, -1)
        assert self.data.group is not None
        P = self.points_of(theta)
        idx = np.searchsorted(np.asarray(self.group_ids), self.data.group)
        r = (p - P[idx]).reshape(-1)
        G = len(self.group_ids)
        Jc = np.zeros((n, 3, 3 * G))
        for a in range(3):
            Jc[np.arange(n), a, 3 * idx + a] = -1.0
        J = np.concatenate([Jm, Jc], axis=2).reshape(3 * n, -1)
        if self.data.kind == "gauge":
            assert self.data.distance_m is not None
            dvec = P[1] - P[0]
            dist = float(np.linalg.norm(dvec))
            u = dvec / dist if dist > 0 else np.zeros(3)
            w = self.gauge_weight
            row = np.zeros((1, J.shape[1]))
            row[0, len(self.free) : len(self.free) + 3] = -w * u
            row[0, len(self.free) + 3 : len(self.free) + 6] = w * u
            r = np.concatenate([r, [w * (dist - self.data.distance_m)]])
            J = np.concatenate([J, row])
        return r, J

    def residuals(self, theta: ArrayLike) -> FloatArray:
        """Residual vector only (m)."""
        p = self.model.points(self.data.q_rad, self.x_of(theta))
        if self.data.kind == "points":
            assert self.data.p_world_m is not None
            return (p - self.data.p_world_m).reshape(-1)
        assert self.data.group is not None
        P = self.points_of(theta)
        r = (p - P[np.searchsorted(np.asarray(self.group_ids), self.data.group)]).reshape(-1)
        if self.data.kind == "gauge":
            assert self.data.distance_m is not None
            gap = float(np.linalg.norm(P[1] - P[0])) - self.data.distance_m
            r = np.concatenate([r, [self.gauge_weight * gap]])
        return r

    @property
    def gauge_weight(self) -> float:
        """Weight of the gauge-distance residual: √poses, as much as all the contacts together."""
        return math.sqrt(self.data.n_poses)

    def priority(self) -> FloatArray:
        """Base-set preference over ``θ`` (contact points first)."""
        pri = _priority(self.model)[list(self.free)]
        return np.concatenate([pri, np.zeros(3 * len(self.group_ids))])


def marker_axis_distances(
    model: ErrorModel, q_rad: ArrayLike, x: ArrayLike | None = None
) -> dict[str, float]:
    """Largest distance (m) over the poses of the tool point from each revolute joint's axis."""
    q = np.atleast_2d(np.asarray(q_rad, dtype=np.float64))
    xa = np.zeros(model.n_params) if x is None else np.asarray(x, dtype=np.float64)
    _, blocks = model._walk(xa, q)
    p = model.points(q, xa)
    out: dict[str, float] = {}
    joints = {j.name: j for j in model.chain.movable}
    for group, _, T_after in blocks:
        j = joints.get(group)
        if j is None or j.type != "revolute":
            continue
        a = T_after[:, :3, :3] @ np.asarray(j.axis)
        v = p - T_after[:, :3, 3]
        out[group] = float(np.max(np.linalg.norm(np.cross(a, v), axis=1)))
    return out


def scale_direction(problem: Problem, theta: ArrayLike) -> FloatArray:
    """The direction in ``θ`` that grows every length and contact point by the same factor (``(n_theta,)``).

    Touch data cannot see it: a uniformly scaled arm touches uniformly scaled points.
    """
    t = np.asarray(theta, dtype=np.float64)
    x = problem.x_of(t)
    v = np.zeros(problem.n_theta)
    movable = {j.name: j for j in problem.model.chain.movable}
    tool_xyz = problem.model.T_tip_tool[:3, 3]
    for col, i in enumerate(problem.free):
        p = problem.model.parameters[i]
        axis = "xyz".find(p.kind) if p.kind in ("x", "y", "z") else -1
        if axis >= 0 and p.group in movable:
            v[col] = movable[p.group].origin_xyz_m[axis] + x[i]
        elif axis >= 0 and p.group == "tool":
            v[col] = tool_xyz[axis] + x[i]
        elif p.kind == "offset" and p.group in movable and movable[p.group].type == "prismatic":
            v[col] = x[i]
    v[len(problem.free) :] = t[len(problem.free) :]
    return v


def _reasons(problem: Problem, on_axis: set[str], still: dict[str, float], scale_lost: set[int]) -> Explain:
    model, names = problem.model, problem.names
    kind = problem.data.kind

    def explain(col: int, same: tuple[tuple[str, float], ...], is_zero: bool) -> str:
        name = names[col]
        group, _, k = name.partition(".")
        if col in scale_lost:
            return (
                "touch data does not show the arm's overall size, so this length stays nominal and sets the "
                "scale; measure a known distance (--kind gauge) to identify it"
            )
        if group in on_axis:
            return (
                f"the marker is on the {group} axis, so turning {group} does not move it; move the marker "
                f"off the {group} axis (a few centimetres) and measure again"
            )
        if group in still:
            return f"{group} did not move in the poses (always {still[group]:.4g}); move it through its range"
        if group == "tool" and k.startswith("r"):
            return (
                "a measured point does not show the tool's orientation (measure a frame, e.g. a tag, for it)"
            )
        common = common_reason(group, k, same, is_zero, "measured points")
        if common is not None:
            return common
        if len(same) == 1:
            other, c = same[0]
            return f"moves the points exactly like {other} (×{c:.3g}); {other} is identified instead"
        others = ", ".join(n for n, _ in same[:4])
        if kind in ("touch", "gauge") and group in (model.chain.movable[0].name, "base"):
            return f"touch data has no outside frame: cannot be told apart from the contact points ({others})"
        return f"cannot be told apart from a combination of {others}"

    return explain


def analyse(problem: Problem, theta: ArrayLike | None = None, *, tolerance: float = 1e-8) -> Identifiability:
    """Identifiability of the problem's unknowns at ``θ`` (default: the initial guess), with user reasons.

    Reasons checked first: the marker on a revolute joint's axis (that joint's parameters do not move it) and a
    joint that did not move across the poses.
    """
    t = problem.initial_theta() if theta is None else np.asarray(theta, dtype=np.float64)
    _, J = problem.residuals_and_jacobian(t)
    x = problem.x_of(t)
    dist = marker_axis_distances(problem.model, problem.data.q_rad, x)
    on_axis = {name for name, d in dist.items() if d < 1e-6}
    still = still_joints(problem.model.chain.movable, problem.data.q_rad)
    scale_lost: set[int] = set()
    if problem.data.kind == "touch":
        v = scale_direction(problem, t)
        norms = np.linalg.norm(J, axis=0)
        norms[norms == 0.0] = 1.0
        _, sv, Vt = np.linalg.svd(J / norms, full_matrices=False)
        Vr = Vt[: int(np.sum(sv > tolerance * sv[0]))]
        v = Vr.T @ (Vr @ (v * norms))  # the part of the scale direction the other unknowns do not cover
        if float(v @ v) > 0.0:
            J_seen = (J / norms - np.outer((J / norms) @ v, v) / float(v @ v)) * norms
            first = analyse_columns(J_seen, problem.names, priority=problem.priority(), tolerance=tolerance)
            B = J[:, list(first.base)]
            for u in first.unidentifiable:
                c = problem.names.index(u.name)
                resid = J[:, c] - B @ np.linalg.lstsq(B, J[:, c], rcond=None)[0]
                if float(np.linalg.norm(resid)) > 1e-6 * float(np.linalg.norm(J[:, c])):
                    scale_lost.add(c)
            J = J_seen
    explain = _reasons(problem, on_axis, still, scale_lost)
    return analyse_columns(
        J, problem.names, priority=problem.priority(), tolerance=tolerance, explain=explain
    )


def free_indices(model: ErrorModel, exclude_groups: Sequence[str] = ()) -> tuple[int, ...]:
    """Indices of the model parameters whose group is not in ``exclude_groups``."""
    return tuple(i for i, p in enumerate(model.parameters) if p.group not in exclude_groups)


PLAN_CRITERIA: tuple[str, ...] = ("I", "D")
"""Pose-planning criteria: ``I`` (smallest average prediction variance of the tool point), ``D`` (largest O1)."""


def plan_poses(
    model: ErrorModel,
    q_candidates: ArrayLike,
    n_poses: int,
    *,
    exclude_groups: Sequence[str] = ("base",),
    criterion: str = "D",
    prior_sigma: ArrayLike | None = None,
    noise_m: float = 0.5e-3,
) -> IntArray:
    """Pick ``n_poses`` of the candidate configurations that best identify the model, greedily.

    ``D``: each pose maximises ``det(JᵀJ)`` of the identifiable base set (O1). ``I``: each pose minimises the
    tool point's prediction variance averaged over the candidates (:func:`~robocal.core.identifiability.
    select_poses_i_optimal`); with ``prior_sigma`` (Bayesian) every parameter that has a prior σ counts, the
    poses then aim at what the prior does not already settle, weighed against the marker noise ``noise_m``.

    Args:
        model: The nominal error model (with the tool the measurements will see).
        q_candidates: ``(M, n_q)`` configurations inside the joint limits.
        n_poses: How many to pick.
        exclude_groups: Parameter groups that are not estimated (``base`` when the points are measured in the
            base frame).
        criterion: ``D`` or ``I`` (:data:`PLAN_CRITERIA`).
        prior_sigma: ``(P,)`` prior σ of each model parameter (``inf``: none); ``I`` only.
        noise_m: Marker noise per axis (m) the prior is weighed against.

    Returns:
        ``(n_poses,)`` indices into ``q_candidates``, in the order chosen.
    """
    if criterion not in PLAN_CRITERIA:
        raise UsageError(f"pose-planning criterion {criterion!r}; valid: {', '.join(PLAN_CRITERIA)}")
    if not (math.isfinite(noise_m) and noise_m > 0.0):
        raise UsageError(f"marker noise must be a positive length, got {noise_m} m")
    q = model.chain.check_q(q_candidates, what="candidate pose")
    problem = Problem(
        model,
        Measurements("points", q, model.points(q)),
        free_indices(model, exclude_groups),
        np.zeros(model.n_params),
    )
    ident = analyse(problem)
    _, J = problem.residuals_and_jacobian(problem.initial_theta())
    cols = list(ident.base)
    if criterion == "D":
        Jc = (J[:, cols] / ident.column_norms[cols]).reshape(q.shape[0], 3, len(cols))
        return select_poses(Jc, n_poses)
    precision = None
    if prior_sigma is not None:
        sig = np.asarray(prior_sigma, dtype=np.float64)
        if sig.shape != (model.n_params,) or np.any(np.isnan(sig)) or np.any(sig <= 0.0):
            raise UsageError(f"prior σ must be {model.n_params} positive values (inf for none)")
        sig_free = sig[list(problem.free)]
        cols = sorted(set(cols) | {c for c in range(len(problem.free)) if math.isfinite(sig_free[c])})
        precision = np.where(np.isfinite(sig_free[cols]), 1.0 / sig_free[cols] ** 2, 0.0)
    Jc = (J[:, cols] / noise_m).reshape(q.shape[0], 3, len(cols))
    # the prediction is the tool point in the chain's base frame: a registration (base) does not change it
    seen = np.array([model.parameters[problem.free[c]].group != "base" for c in cols])
    Jp = Jc * seen
    return select_poses_i_optimal(Jc, n_poses, J_predict=Jp, prior_precision=precision)


def dh_like_constraints(
    problem: Problem, *, parallel_tol: float = 1e-3
) -> tuple[FloatArray, tuple[str, ...]]:
    """Rows ``C`` with ``C θ = 0`` that restrict the model to what a DH parametrisation can express.

    DH has no parameter for tilting a joint axis towards or away from a *parallel* previous axis (Hayati's β,
    a rotation about the direction normal to both the axis and the link between the two axes). For each joint
    whose axis is parallel to the previous movable joint's at the nominal zero pose, that tilt is held at zero.

    Returns:
        ``(c, n_theta)`` constraint rows (unit vectors on the joint's rotation parameters) and the joints held.
    """
    model = problem.model
    _, blocks = model._walk(np.zeros(model.n_params), np.zeros((1, model.chain.n_q)))
    frames = {group: T_after[0] for group, _, T_after in blocks}
    rows: list[FloatArray] = []
    held: list[str] = []
    prev = None
    for j in model.chain.movable:
        T = frames[j.name]
        if prev is not None and j.type == "revolute" and prev[0].type == "revolute":
            a_j = T[:3, :3] @ np.asarray(j.axis)
            a_p = prev[1][:3, :3] @ np.asarray(prev[0].axis)
            if float(np.linalg.norm(np.cross(a_j, a_p))) < parallel_tol:
                link = T[:3, 3] - prev[1][:3, 3]
                perp = link - (link @ a_j) * a_j
                if float(np.linalg.norm(perp)) > 1e-9:
                    beta_world = np.cross(a_j, perp / np.linalg.norm(perp))
                    beta_local = T[:3, :3].T @ beta_world
                    row = np.zeros(problem.n_theta)
                    for k, kind in enumerate(("rx", "ry", "rz")):
                        idx = model.index(f"{j.name}.{kind}")
                        if idx in problem.free:
                            row[problem.free.index(idx)] = beta_local[k]
                    if np.any(row):
                        rows.append(row)
                        held.append(j.name)
        prev = (j, T)
    return (np.array(rows) if rows else np.zeros((0, problem.n_theta))), tuple(held)
