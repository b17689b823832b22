"""Poses for contact (touch, gauge) and camera (tag) sessions: reaching a point, seeing a target (pure numpy).

A touch or gauge session cannot use free configurations: each pose must put the tool tip on one of a few fixed
points. :func:`reach_point` finds configurations inside the joint limits that do, by damped least squares from
many starts at once; :func:`plan_contact_poses` picks the ones that best identify the model, greedily and
I-optimal (the smallest average prediction variance of the tool point over free configurations), the contact
points being unknowns of the fit like the model's parameters. :func:`target_visible` says which poses show a
camera the whole target; :func:`plan_image_poses` picks among them greedily and I-optimal for the reprojection
model of :class:`~robocal.core.kinematic_images.ImageProblem` (camera pose, target mounting and, on request, the
intrinsics being unknowns with the kinematics).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from ..errors import ShapeMismatchError, UsageError
from .arrays import BoolArray, FloatArray, IntArray
from .identifiability import Identifiability, select_poses, select_poses_i_optimal
from .kinematic_errors import ErrorModel
from .kinematic_images import ImageObservations, ImageProblem, project
from .kinematic_problem import Measurements, Problem, analyse, free_indices

__all__ = [
    "ImagePlan",
    "image_plan_problem",
    "plan_contact_poses",
    "plan_image_poses",
    "reach_point",
    "target_visible",
]


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


def target_visible(
    T_cam_target: ArrayLike,
    corners_m: ArrayLike,
    front_normal: ArrayLike,
    K: ArrayLike,
    size: tuple[int, int],
    *,
    min_depth_m: float = 0.15,
    margin_px: float = 20.0,
    max_angle_deg: float = 60.0,
) -> BoolArray:
    """Which target poses a pinhole camera sees whole: facing it, in front of it, every corner inside the image.

    Args:
        T_cam_target: ``(N, 4, 4)`` target poses in the camera frame (OpenCV: z forward, y down).
        corners_m: ``(K, 3)`` the target's corners in its own frame, m.
        front_normal: ``(3,)`` outward normal of the printed face in the target frame.
        K: ``(3, 3)`` camera matrix.
        size: Image ``(width, height)``, pixels.
        min_depth_m: Every corner at least this far in front of the camera.
        margin_px: Every corner at least this far inside the image border.
        max_angle_deg: The largest angle between the face's normal and the direction to the camera.

    Returns:
        ``(N,)`` True where the camera sees the whole target.
    """
    T = np.asarray(T_cam_target, dtype=np.float64)
    obj = np.asarray(corners_m, dtype=np.float64)
    Km = np.asarray(K, dtype=np.float64)
    n = np.einsum("nij,j->ni", T[:, :3, :3], np.asarray(front_normal, dtype=np.float64))
    dist = np.linalg.norm(T[:, :3, 3], axis=1)
    with np.errstate(divide="ignore", invalid="ignore"):
        to_cam = -T[:, :3, 3] / dist[:, None]
    facing = np.sum(n * to_cam, axis=1) > math.cos(math.radians(max_angle_deg))
    pc = np.einsum("nij,kj->nki", T[:, :3, :3], obj) + T[:, None, :3, 3]
    z = pc[..., 2]
    uv = np.einsum("ij,nkj->nki", Km, pc)
    with np.errstate(divide="ignore", invalid="ignore"):
        u, v = uv[..., 0] / uv[..., 2], uv[..., 1] / uv[..., 2]
    w, h = size
    inside = (z > min_depth_m) & (u > margin_px) & (u < w - margin_px) & (v > margin_px) & (v < h - margin_px)
    return np.asarray(facing & inside.all(axis=1), dtype=np.bool_)


def image_plan_problem(
    model: ErrorModel,
    q_rad: ArrayLike,
    corners_m: ArrayLike,
    K: ArrayLike,
    *,
    camera_on_tool: bool = False,
    refine_intrinsics: bool = False,
) -> ImageProblem:
    """The reprojection problem of a planned image session: every corner seen where the nominal model puts it.

    Args:
        model: Nominal error model in the measurement frame: camera fixed, ``T_world_base`` is the camera → base
            pose and ``T_tip_tool`` the target's mounting; camera on the tool, ``T_world_base`` is the target →
            base pose and ``T_tip_tool`` the camera's mounting.
        q_rad: ``(N, n_q)`` configurations (each must show the whole target).
        corners_m: ``(K, 3)`` the target's corners in its frame, m.
        K: ``(3, 3)`` camera matrix.
        camera_on_tool: The set-up.
        refine_intrinsics: ``fx, fy, cx, cy`` are unknowns too.

    Returns:
        The problem over every model parameter (and the intrinsics), at its nominal values.
    """
    q = model.chain.check_q(q_rad, what="candidate pose")
    c = np.asarray(corners_m, dtype=np.float64)
    if c.ndim != 2 or c.shape[1] != 3 or c.shape[0] < 3:
        raise ShapeMismatchError(f"target corners must be (K >= 3, 3), got {c.shape}")
    Km = np.asarray(K, dtype=np.float64)
    n, k = q.shape[0], c.shape[0]
    T = model.tool_poses(q)  # camera fixed: T_cam_target; camera on the tool: T_target_cam
    if camera_on_tool:
        p = np.einsum("nji,nkj->nki", T[:, :3, :3], c[None, :, :] - T[:, None, :3, 3])
    else:
        p = np.einsum("nij,kj->nki", T[:, :3, :3], c) + T[:, None, :3, 3]
    uv, _ = project(p.reshape(-1, 3))
    data = ImageObservations(
        q, np.repeat(np.arange(n), k), np.tile(c, (n, 1)), uv, float(Km[0, 0] + Km[1, 1]) / 2, K=Km
    )
    return ImageProblem(
        model, data, tuple(range(model.n_params)), np.zeros(model.n_params),
        camera_on_tool=camera_on_tool, refine_intrinsics=refine_intrinsics,
    )  # fmt: skip


@dataclass(frozen=True, eq=False)
class ImagePlan:
    """Poses chosen for an image session.

    Attributes:
        index: ``(n_poses,)`` indices into the candidates, in the order chosen.
        identifiability: What the chosen images identify (rank, base set, reasons, observability).
        candidates: What images at every candidate would identify.
        prediction_sigma_m: Predicted one-σ error after identification of the measured point (the target's
            centre in the camera frame; camera on the tool: the camera's centre in the target frame), RMS over
            the candidates, at the pixel noise given, linearised at nominal; m (NaN if singular).
    """

    index: IntArray
    identifiability: Identifiability
    candidates: Identifiability
    prediction_sigma_m: float


def _image_blocks(
    problem: ImageProblem, cols: list[int], noise_px: float
) -> tuple[FloatArray, FloatArray]:
    """Per-pose whitened Jacobian blocks of the columns ``(N, 2K, k)`` and the measured point's ``(N, 3, k)``."""
    _, J = problem.residuals_and_jacobian(problem.initial_theta())
    n = problem.data.n_poses
    Jc = (J[:, cols] / noise_px).reshape(n, -1, len(cols))
    n_free = len(problem.free)
    _, Jm = problem.model.point_jacobian(problem.data.q_rad)
    Jp = np.zeros((n, 3, len(cols)))
    for j, col in enumerate(cols):
        if col < n_free:  # the intrinsics do not move the measured point
            Jp[:, :, j] = Jm[:, :, problem.free[col]]
    return Jc, Jp


def _prior_columns(
    problem: ImageProblem, ident: Identifiability, prior_sigma: ArrayLike | None
) -> tuple[list[int], FloatArray | None]:
    """The unknowns a plan counts (the base set, plus every one with a prior) and their prior precision."""
    cols = list(ident.base)
    if prior_sigma is None:
        return cols, None
    n_params = problem.model.n_params
    sig = np.asarray(prior_sigma, dtype=np.float64)
    if sig.shape != (n_params,) or np.any(np.isnan(sig)) or np.any(sig <= 0.0):
        raise UsageError(f"prior σ must be {n_params} positive values (inf for none)")
    sig_free = np.full(problem.n_theta, np.inf)  # the intrinsics have no prior
    sig_free[: len(problem.free)] = sig[list(problem.free)]
    cols = sorted(set(cols) | {c for c in range(problem.n_theta) if math.isfinite(sig_free[c])})
    return cols, np.where(np.isfinite(sig_free[cols]), 1.0 / sig_free[cols] ** 2, 0.0)


def plan_image_poses(
    model: ErrorModel,
    q_candidates: ArrayLike,
    corners_m: ArrayLike,
    K: ArrayLike,
    n_poses: int,
    *,
    camera_on_tool: bool = False,
    refine_intrinsics: bool = False,
    noise_px: float = 0.3,
    prior_sigma: ArrayLike | None = None,
) -> ImagePlan:
    """Pick ``n_poses`` image poses greedily, I-optimal for the measured point over the candidates.

    The unknowns are the identifiable base set of the reprojection problem over all candidates (kinematics,
    camera pose or target place, the mounting and, with ``refine_intrinsics``, ``fx, fy, cx, cy``); each step
    adds the image that lowers most the prediction variance of the target's centre in the camera frame (camera
    on the tool: the camera's centre in the target frame), averaged over the candidates
    (:func:`~robocal.core.identifiability.select_poses_i_optimal`; the first images are D-optimal until the
    information has full rank). With ``prior_sigma`` the plan is Bayesian, for the fit ``identify --kind tag
    --prior`` makes: every parameter with a prior σ is an unknown too, the prior's information
    ``diag(1/σ²)`` is counted as known beforehand (weighed against ``noise_px``), and after the same D-optimal
    first images (the camera pose and the mounting have no prior: the images alone must fix them) each image
    goes where the prior and the images so far leave the most uncertainty.

    Args:
        model: Nominal error model of the set-up (see :func:`image_plan_problem`).
        q_candidates: ``(M, n_q)`` configurations where the camera sees the whole target.
        corners_m: ``(K, 3)`` the target's corners in its frame, m.
        K: ``(3, 3)`` camera matrix.
        n_poses: How many images.
        camera_on_tool: The set-up.
        refine_intrinsics: Plan for a fit that refines ``fx, fy, cx, cy``.
        noise_px: Corner noise per axis, pixels (scales the predicted σ; weighs the images against the prior).
        prior_sigma: ``(P,)`` prior σ of each model parameter (``inf``: none, e.g. the camera pose and the
            mounting; m or rad); the intrinsics have none.

    Raises:
        UsageError: Fewer candidates than images, too few images for the identifiable unknowns, a noise that is
            not a positive number, a prior σ that is not positive.
    """
    if not (math.isfinite(noise_px) and noise_px > 0.0):
        raise UsageError(f"--noise-px must be a positive number, got {noise_px}")
    problem = image_plan_problem(
        model, q_candidates, corners_m, K, camera_on_tool=camera_on_tool, refine_intrinsics=refine_intrinsics
    )
    n_cand = problem.data.n_poses
    if n_cand < n_poses:
        raise UsageError(f"--poses {n_poses}: the camera sees the whole target in only {n_cand} candidate poses")
    ident = problem.analyse()
    if 6 * n_poses <= ident.rank:  # an image shows the target's pose: 6 numbers, whatever its corner count
        raise UsageError(
            f"too few poses: {n_poses} images show {6 * n_poses} numbers (the target's pose in each), not more "
            f"than the {ident.rank} unknowns the candidates can identify; plan at least {ident.rank // 6 + 2} "
            "images (20 or more for a useful result)"
        )
    cols, precision = _prior_columns(problem, ident, prior_sigma)
    Jc, Jp = _image_blocks(problem, cols, noise_px)
    start: list[int] = []
    if precision is not None:  # the images alone must fix the camera pose and the mounting (no prior on them):
        # the first ones are D-optimal for the base set, as without a prior (greedy I from the prior alone
        # chose worse plans, measured by its own criterion)
        base_cols = [cols.index(c) for c in ident.base]
        start = select_poses(Jc[:, :, base_cols], min(n_poses, -(-len(base_cols) // Jc.shape[1]) + 1)).tolist()
    idx = select_poses_i_optimal(Jc, n_poses, J_predict=Jp, prior_precision=precision, start=start)
    chosen = image_plan_problem(
        model, problem.data.q_rad[idx], corners_m, K, camera_on_tool=camera_on_tool,
        refine_intrinsics=refine_intrinsics,
    ).analyse()  # fmt: skip
    A = np.einsum("nrk,nrl->kl", Jc[idx], Jc[idx])
    if precision is not None:
        A += np.diag(precision)
    try:
        cov = np.linalg.inv(A)
    except np.linalg.LinAlgError:
        sigma = math.nan
    else:
        per_row = np.einsum("nrk,kl,nrl->n", Jp, cov, Jp)
        sigma = float(np.sqrt(max(float(np.mean(per_row)), 0.0))) if np.all(np.isfinite(per_row)) else math.nan
    return ImagePlan(np.asarray(idx, dtype=np.int64), chosen, ident, sigma)
