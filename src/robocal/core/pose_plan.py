"""Poses for contact sessions (touch, gauge): reaching a fixed point, and choosing among such poses (pure numpy).

A touch or gauge session cannot use free configurations: each pose must put the tool tip on one of a few fixed
points. :func:`reach_point` finds configurations inside the joint limits that do, by damped least squares from
many starts at once; :func:`plan_contact_poses` picks the ones that best identify the model, greedily and
I-optimal (the smallest average prediction variance of the tool point over free configurations), the contact
points being unknowns of the fit like the model's parameters.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from numpy.typing import ArrayLike

from ..errors import ShapeMismatchError, UsageError
from .arrays import FloatArray, IntArray
from .identifiability import select_poses_i_optimal
from .kinematic_errors import ErrorModel
from .kinematic_problem import Measurements, Problem, analyse, free_indices

__all__ = ["plan_contact_poses", "reach_point"]


def reach_point(
    model: ErrorModel,
    target_m: ArrayLike,
    q_start: ArrayLike,
    limits: tuple[ArrayLike, ArrayLike],
    *,
    x: ArrayLike | None = None,
    iterations: int = 80,
    tolerance_m: float = 1e-9,
) -> FloatArray:
    """Configurations whose tool point is ``target_m``: damped least-squares IK from many starts at once.

    Args:
        model: The error model (its tool point is what touches).
        target_m: ``(3,)`` point in the model's world frame, m.
        q_start: ``(M, n_q)`` start configurations.
        limits: ``(lower, upper)`` ``(n_q,)`` bounds every step is clipped to.
        x: Model parameters (default: nominal).
        iterations: Gauss–Newton steps.
        tolerance_m: Distance from the target a result may keep.

    Returns:
        ``(K, n_q)`` the configurations that reached the target (``K <= M``).
    """
    target = np.asarray(target_m, dtype=np.float64)
    if target.shape != (3,) or not np.all(np.isfinite(target)):
        raise ShapeMismatchError(f"target must be a finite (3,) point, got {target.tolist()}")
    lo, up = (np.asarray(v, dtype=np.float64) for v in limits)
    xa = np.zeros(model.n_params) if x is None else np.asarray(x, dtype=np.float64)
    cols = [model.index(f"{j.name}.offset") for j in model.chain.movable]
    q: FloatArray = np.clip(np.array(q_start, dtype=np.float64), lo, up)
    for _ in range(iterations):
        p, J = model.point_jacobian(q, xa)
        Jq = J[:, :, cols]
        A = Jq @ Jq.transpose(0, 2, 1) + 1e-6 * np.eye(3)
        dq = np.einsum("mij,mi->mj", Jq, np.linalg.solve(A, (target - p)[:, :, None])[:, :, 0])
        q = np.clip(q + dq, lo, up)
    ok = np.linalg.norm(target - model.points(q, xa), axis=1) < tolerance_m
    return np.asarray(q[ok], dtype=np.float64)


def plan_contact_poses(
    model: ErrorModel,
    q_candidates: ArrayLike,
    group: ArrayLike,
    n_poses: int,
    q_predict: ArrayLike,
    *,
    kind: str = "touch",
    distance_m: float | None = None,
    exclude_groups: Sequence[str] = ("base",),
) -> IntArray:
    """Pick ``n_poses`` contact configurations greedily, I-optimal for the tool point at ``q_predict``.

    The unknowns are the identifiable base set of a ``kind`` session over all candidates (model parameters and
    the contact points); the prediction is the tool point at the free configurations ``q_predict`` (the contact
    points do not enter it). The first poses are D-optimal until the information matrix has full rank.

    Args:
        model: The nominal error model.
        q_candidates: ``(M, n_q)`` configurations, each touching the point of its group.
        group: ``(M,)`` contact group per candidate (``gauge``: 0 = socket A, 1 = socket B).
        n_poses: How many to pick.
        q_predict: ``(Mp, n_q)`` configurations the identified model should predict well.
        kind: ``touch`` or ``gauge``.
        distance_m: Socket distance (``gauge`` only).
        exclude_groups: Parameter groups that are not estimated.

    Returns:
        ``(n_poses,)`` indices into ``q_candidates``, in the order chosen.
    """
    if kind not in ("touch", "gauge"):
        raise UsageError(f"contact planning is for touch or gauge sessions, not {kind!r}")
    q = model.chain.check_q(q_candidates, what="candidate pose")
    data = Measurements(kind, q, group=np.asarray(group), distance_m=distance_m)
    problem = Problem(model, data, free_indices(model, exclude_groups), np.zeros(model.n_params))
    ident = analyse(problem)
    _, J = problem.residuals_and_jacobian(problem.initial_theta())
    cols = list(ident.base)
    n = q.shape[0]
    norms = ident.column_norms[cols]
    Jc = (J[: 3 * n, cols] / norms).reshape(n, 3, len(cols))
    qp = model.chain.check_q(q_predict, what="prediction pose")
    _, Jp_all = model.point_jacobian(qp)
    n_free = len(problem.free)
    Jp = np.zeros((qp.shape[0], 3, len(cols)))
    for c, i in enumerate(cols):
        if i < n_free and model.parameters[problem.free[i]].group not in ("base",):
            Jp[:, :, c] = Jp_all[:, :, problem.free[i]] / norms[c]
    return select_poses_i_optimal(Jc, n_poses, J_predict=Jp)
