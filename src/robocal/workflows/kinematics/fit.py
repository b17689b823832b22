"""Least-squares estimation of kinematic parameters (scipy ``least_squares``), validation and covariance.

Only the identifiable base set (:func:`robocal.core.kinematic_problem.analyse`) is estimated; every other
parameter stays nominal. Levenberg–Marquardt (``method="lm"``) on vector residuals by default; ``trf`` with a
Huber loss when outliers are expected, or with a Gaussian prior pulling each parameter towards nominal when
poses are few. scipy comes with the ``kinematics`` extra and is imported only here.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from ...backends import require
from ...core.arrays import FloatArray
from ...core.identifiability import Identifiability
from ...core.kinematic_errors import ErrorModel
from ...core.kinematic_images import ImageProblem
from ...core.kinematic_problem import Measurements, Problem, analyse
from ...errors import UsageError

__all__ = [
    "CONSTRAINT_WEIGHT",
    "PRIOR_SIGMA_MIN",
    "FitResult",
    "PriorSigmas",
    "check_seed",
    "fit",
    "predicted_error_m",
    "prediction_rms_m",
    "split_validation",
    "structural_image_analysis",
    "validation_errors",
]



PRIOR_SIGMA_MIN = 1e-9
"""Smallest prior σ (m or rad): a tighter one would weigh more than float64 can hold against the data."""

CONSTRAINT_WEIGHT = 100.0
"""Metres of residual per unit of a constraint row: holds constrained directions to ~1e-8 at 1 µm residuals."""


def _least_squares() -> Any:
    optimize = require(
        "scipy.optimize",
        "kinematic identification",
        message="kinematic identification needs scipy: pip install 'robocal[kinematics]'",
    )
    return optimize.least_squares


@dataclass(frozen=True)
class PriorSigmas:
    """A Gaussian prior around the nominal model: the manufacturing tolerance of the arm's URDF.

    With a prior every model parameter that has one is estimated (maximum a posteriori), not only the
    identifiable base set: the prior decides the directions the data cannot see, and shrinks the poorly seen
    ones. The defaults are the tolerance of a printed hobby arm (SO-101, Koch): origins ±1 mm, axis tilts ±0.5°,
    servo zeros ±2°, tool point ±1 mm.

    Attributes:
        length_m: Origin translations, the tool point and prismatic offsets (m).
        angle_rad: Origin rotations (tilts) and the tool's rotation (rad).
        offset_rad: Revolute joint zero offsets (rad).
        noise_m: Measurement noise per residual (m, pixels for images); None: estimated from the residuals of
            a fit without the prior.
    """

    length_m: float = 1e-3
    angle_rad: float = math.radians(0.5)
    offset_rad: float = math.radians(2.0)
    noise_m: float | None = None

    def __post_init__(self) -> None:
        for name, top in (("length_m", 1.0), ("angle_rad", math.pi), ("offset_rad", math.pi)):
            v = getattr(self, name)
            if not (math.isfinite(v) and v > 0):
                raise UsageError(f"prior {name}: must be a positive number, got {v}")
            if not PRIOR_SIGMA_MIN <= v <= top:
                raise UsageError(f"prior {name}: must be from {PRIOR_SIGMA_MIN:g} to {top:g}, got {v:g}")
        if self.noise_m is not None and not (math.isfinite(self.noise_m) and self.noise_m > 0):
            raise UsageError(f"prior noise: must be a positive number, got {self.noise_m}")

    def model_sigmas(self, model: ErrorModel, *, tool_free: bool = False) -> FloatArray:
        """Prior σ of each model parameter, ``(P,)``.

        ``inf`` (no prior) for the base and, with ``tool_free``, the tool (a target's mounting on the tip link).
        """
        out = np.full(model.n_params, np.inf)
        for i, p in enumerate(model.parameters):
            if p.group == "base" or (tool_free and p.group == "tool"):
                continue
            if p.kind == "offset":
                out[i] = self.offset_rad if p.unit == "rad" else self.length_m
            else:
                out[i] = self.length_m if p.unit == "m" else self.angle_rad
        return out

    def sigmas(self, problem: Problem | ImageProblem) -> FloatArray:
        """Prior σ of each unknown ``θ`` of ``problem``, ``(n_theta,)``.

        ``inf`` (no prior) for the base (a registration or the camera pose), the tool of an image problem (the
        target's mounting) and contact points.
        """
        out = np.full(problem.n_theta, np.inf)
        per_param = self.model_sigmas(problem.model, tool_free=isinstance(problem, ImageProblem))
        out[: len(problem.free)] = per_param[list(problem.free)]
        return out


@dataclass(frozen=True, eq=False)
class FitResult:
    """An identification result.

    Attributes:
        problem: The problem that was solved.
        identifiability: Rank, base set and the unidentifiable parameters (at the nominal model).
        theta: ``(n_theta,)`` unknowns after the fit (non-base entries stay at their initial values).
        sigma: ``(n_theta,)`` one-σ uncertainty of each unknown (NaN for those not estimated).
        covariance: ``(k, k)`` covariance of the base-set unknowns, in base-set order.
        x: The full model parameter vector after the fit.
        train_errors_m: Per-pose error norm on the poses used for the fit (m); image problems: RMS
            reprojection error per image (pixels).
        nominal_train_errors_m: The same for the nominal model (start values for image problems).
        method: scipy method used (``lm`` or ``trf``).
        loss: ``linear`` or ``huber``.
        iterations: Function evaluations.
        success: Whether scipy reports convergence.
        estimated: Indices into ``theta`` of the unknowns ``covariance`` is over, in its order.
    """

    problem: Problem | ImageProblem
    identifiability: Identifiability
    theta: FloatArray
    sigma: FloatArray
    covariance: FloatArray
    x: FloatArray
    train_errors_m: FloatArray
    nominal_train_errors_m: FloatArray
    method: str
    loss: str
    iterations: int
    success: bool
    estimated: tuple[int, ...] = ()


def _structural_rank(problem: Problem) -> int:
    """Rank of the model's free parameters with point data from 60 spread configurations."""
    lo, up = problem.model.chain.limits()
    lo = np.where(np.isfinite(lo), lo, -math.pi)
    up = np.where(np.isfinite(up), up, math.pi)
    q = np.random.default_rng(0).uniform(lo, up, (60, lo.size))
    data = Measurements("points", q, problem.model.points(q, problem.x_fixed))
    return analyse(Problem(problem.model, data, problem.free, problem.x_fixed)).rank


def structural_image_analysis(problem: ImageProblem) -> Identifiability:
    """What an image problem's unknowns can reach: its target seen from 60 spread configurations (seeded)."""
    from ...core.pose_plan import image_plan_problem

    lo, up = problem.model.chain.limits()
    lo = np.where(np.isfinite(lo), lo, -math.pi)
    up = np.where(np.isfinite(up), up, math.pi)
    q = np.random.default_rng(0).uniform(lo, up, (60, lo.size))
    data = problem.data
    corners = np.unique(data.corner_m, axis=0)
    K = data.K if data.K is not None else np.diag([data.focal_px, data.focal_px, 1.0])
    seen = image_plan_problem(problem.model, q, corners, K, camera_on_tool=problem.camera_on_tool).data
    spread = ImageProblem(
        problem.model, seen, problem.free, problem.x_fixed, camera_on_tool=problem.camera_on_tool,
        refine_intrinsics=problem.refine_intrinsics,
    )  # fmt: skip
    return spread.analyse()


def _pose_errors(problem: Problem | ImageProblem, theta: FloatArray) -> FloatArray:
    if isinstance(problem, ImageProblem):
        return problem.pose_errors(theta)
    r = problem.residuals(theta)[: 3 * problem.data.n_poses]
    return np.asarray(np.linalg.norm(r.reshape(-1, 3), axis=1), dtype=np.float64)


def fit(
    problem: Problem | ImageProblem,
    *,
    huber_m: float | None = None,
    prior: PriorSigmas | None = None,
    tolerance: float = 1e-8,
    restrict: Sequence[int] | None = None,
    constraints: ArrayLike | None = None,
    structural: Identifiability | None = None,
) -> FitResult:
    """Estimate the identifiable unknowns of ``problem``.

    Args:
        problem: Model, measurements and free parameters.
        huber_m: Use a Huber loss with this scale (m): residuals beyond it count linearly (robust to outliers).
        prior: Add a Gaussian prior towards nominal: every parameter with a prior σ is then estimated (maximum a
            posteriori), the base set too; ``sigma`` and ``covariance`` are the posterior's.
        tolerance: Rank tolerance of the identifiability analysis.
        restrict: Only these ``θ`` indices may be estimated; the base set is then chosen among them.
        constraints: ``(c, n_theta)`` rows ``C`` held at ``C θ = 0`` by stiff penalty rows (e.g. the DH-like
            restriction of :func:`robocal.core.kinematic_problem.dh_like_constraints`).
        structural: An image problem's :func:`structural_image_analysis`, when the caller has it already.

    Returns:
        The :class:`FitResult`.

    Raises:
        UsageError: Too few residuals for the unknowns (names how many poses are needed).
    """
    least_squares = _least_squares()
    if problem.data.n_poses == 0:
        raise UsageError("no poses to fit")
    theta0 = problem.initial_theta()
    if isinstance(problem, ImageProblem):
        ident = problem.analyse(theta0, tolerance=tolerance)
    else:
        ident = analyse(problem, theta0, tolerance=tolerance)
    base = list(ident.base)
    if restrict is not None:
        allowed = set(restrict)
        base = [i for i in base if i in allowed]
    n_res = problem.residuals(theta0).size
    if isinstance(problem, ImageProblem) and restrict is None:
        full = (structural or structural_image_analysis(problem)).rank
        if 6 * problem.data.n_poses <= full:
            raise UsageError(
                f"too few images: {problem.data.n_poses} fitted images show {6 * problem.data.n_poses} numbers "
                f"(the target's pose in each), not more than the {full} unknowns the images could identify; "
                f"take at least {full // 6 + 2} images to fit (20 or more for a useful result)"
            )
    if n_res <= len(base) and isinstance(problem, ImageProblem):
        raise UsageError(
            f"too few target corners: {problem.data.n_poses} images give {n_res} equations for {len(base)} "
            "parameters; take at least 20 images (40 or more for a useful result)"
        )
    if n_res <= len(base):
        assert isinstance(problem, Problem)
        full = _structural_rank(problem)
        need = (full + 3 * len(problem.group_ids)) // 3 + 2
        raise UsageError(
            f"too few poses: {problem.data.n_poses} poses give {n_res} equations, not more than the "
            f"{len(base)} parameters they could identify (the model has {full}); record at least {need} poses "
            "(20 or more for a useful result)"
        )
    C = (
        np.zeros((0, len(base)))
        if constraints is None
        else CONSTRAINT_WEIGHT * np.atleast_2d(constraints)[:, base]
    )
    weights = None
    if prior is not None:
        sig = prior.sigmas(problem)
        allowed_p = set(range(problem.n_theta)) if restrict is None else set(restrict)
        est = sorted(set(base) | {i for i in range(problem.n_theta) if np.isfinite(sig[i]) and i in allowed_p})
        noise = prior.noise_m
        if noise is None:
            plain = fit(
                problem, huber_m=huber_m, tolerance=tolerance, restrict=restrict, constraints=constraints,
                structural=structural,
            )  # fmt: skip
            r0 = problem.residuals(plain.theta)
            noise = max(math.sqrt(float(r0 @ r0) / max(r0.size - len(base), 1)), 1e-12)
            theta0 = plain.theta.copy()
        C = (
            np.zeros((0, len(est)))
            if constraints is None
            else CONSTRAINT_WEIGHT * np.atleast_2d(constraints)[:, est]
        )
        weights = np.where(np.isfinite(sig[est]), noise / sig[est], 0.0)
        base = est
    centre = problem.initial_theta()[base]

    def fun(t_b: FloatArray) -> FloatArray:
        t = theta0.copy()
        t[base] = t_b
        r = problem.residuals(t)
        if weights is not None:
            r = np.concatenate([r, weights * (t_b - centre)])
        return np.concatenate([r, C @ (t_b - centre)])

    def jac(t_b: FloatArray) -> FloatArray:
        t = theta0.copy()
        t[base] = t_b
        _, J = problem.residuals_and_jacobian(t)
        Jb = J[:, base]
        if weights is not None:
            Jb = np.concatenate([Jb, np.diag(weights)])
        return np.concatenate([Jb, C])

    method = "trf" if huber_m is not None else "lm"
    loss = "huber" if huber_m is not None else "linear"
    kwargs: dict[str, Any] = {"method": method, "jac": jac, "x_scale": "jac"}
    if method == "lm":
        kwargs.update(xtol=1e-12, ftol=1e-12, gtol=1e-12, max_nfev=100 * (len(base) + 1))
    else:
        kwargs.update(loss=loss, f_scale=huber_m or 1.0, xtol=1e-12, ftol=1e-12, gtol=1e-12, max_nfev=400)
    sol = least_squares(fun, theta0[base], **kwargs)
    theta = theta0.copy()
    theta[base] = sol.x
    r, J = problem.residuals_and_jacobian(theta)
    Jb = J[:, base]
    if weights is None:
        dof = max(r.size - len(base), 1)
        s2 = float(r @ r) / dof
        info = Jb.T @ Jb
    else:  # the posterior: data with the estimated noise plus the prior
        assert noise is not None
        s2 = noise**2
        info = Jb.T @ Jb + np.diag(weights**2)
    try:
        cov = s2 * np.linalg.inv(info)
    except np.linalg.LinAlgError:
        cov = np.full((len(base), len(base)), np.nan)
    sigma = np.full(theta.size, np.nan)
    sigma[base] = np.sqrt(np.clip(np.diag(cov), 0.0, None))
    return FitResult(
        problem=problem,
        identifiability=ident,
        theta=theta,
        sigma=sigma,
        covariance=cov,
        x=problem.x_of(theta),
        train_errors_m=_pose_errors(problem, theta),
        nominal_train_errors_m=_pose_errors(problem, problem.initial_theta()),
        method=method,
        loss=loss,
        iterations=int(sol.nfev),
        success=bool(sol.success),
        estimated=tuple(int(i) for i in base),
    )


def predicted_error_m(result: FitResult, q_rad: ArrayLike) -> float:
    """RMS (m) over ``q_rad`` of the tool point's predicted error from the fit's covariance.

    See :func:`prediction_rms_m`; the joint readings' own resolution is not in it.

    Args:
        result: A point, touch or gauge fit.
        q_rad: ``(M, n_q)`` poses to predict at, inside the limits.
    """
    problem = result.problem
    assert isinstance(problem, Problem)
    q = np.asarray(q_rad, dtype=np.float64)
    model = problem.model
    at = Problem(model, Measurements("points", q, model.points(q, result.x)), problem.free, result.x)
    n_free = len(problem.free)
    keep = [k for k, i in enumerate(result.estimated) if i < n_free]
    cov = result.covariance[np.ix_(keep, keep)]
    if not np.all(np.isfinite(cov)):
        return math.nan
    return prediction_rms_m(at, [result.estimated[k] for k in keep], cov)


def prediction_rms_m(at: Problem, cols: Sequence[int], cov: FloatArray) -> float:
    """``sqrt(mean_i trace(G_i Σ G_iᵀ))`` (m): the tool point's predicted RMS error over ``at``'s poses.

    ``G_i`` is the tool point's Jacobian at pose ``i`` (at ``at``'s initial unknowns) over the free parameters
    ``cols``, ``Σ`` their ``(k, k)`` covariance; a registration of the base does not move the predicted point.
    """
    _, G = at.residuals_and_jacobian(at.initial_theta())
    seen = np.array([at.model.parameters[at.free[c]].group != "base" for c in cols])
    Gs = G[:, list(cols)] * seen
    return float(np.sqrt(np.einsum("rk,kl,rl->", Gs, cov, Gs) / at.data.n_poses))


def check_seed(seed: int) -> int:
    """``--seed`` as given, checked: numpy seeds are non-negative integers.

    Raises:
        UsageError: A negative seed.
    """
    if seed < 0:
        raise UsageError(f"--seed must be a non-negative integer, got {seed}")
    return seed


def split_validation(data: Measurements, fraction: float, seed: int = 0) -> tuple[FloatArray, FloatArray]:
    """Row indices ``(train, validation)``: a seeded random ``fraction`` held out.

    Touch and gauge groups keep at least three training poses each; ``fraction`` 0 holds nothing out.
    """
    if not 0.0 <= fraction < 1.0:
        raise UsageError(f"--validate-fraction must be in [0, 1), got {fraction}")
    n = data.n_poses
    rng = np.random.default_rng(seed)
    order = rng.permutation(n)
    n_val = round(fraction * n)
    if data.group is None:
        val = np.sort(order[:n_val])
    else:
        counts = {g: int(np.sum(data.group == g)) for g in data.groups()}
        chosen: list[int] = []
        for i in order:
            if len(chosen) >= n_val:
                break
            g = int(data.group[i])
            if counts[g] > 3:
                counts[g] -= 1
                chosen.append(int(i))
        val = np.sort(np.asarray(chosen, dtype=np.int64))
    train = np.setdiff1d(np.arange(n), val)
    if train.size < 2:
        raise UsageError(
            f"--validate-fraction {fraction} holds out {val.size} of {n} poses and leaves {train.size} to fit; "
            "lower it (0.2-0.3 is usual)"
        )
    return train.astype(np.int64), val.astype(np.int64)


def validation_errors(result: FitResult, data: Measurements, x: ArrayLike | None = None) -> FloatArray:
    """Per-pose error norms (m) of held-out poses under the fitted (or given) parameters.

    Points: distance between the predicted and the measured point. Touch/gauge: distance between the predicted
    tool point and its group's fitted contact point.
    """
    xa = result.x if x is None else np.asarray(x, dtype=np.float64)
    p = result.problem.model.points(data.q_rad, xa)
    if data.kind == "points":
        assert data.p_world_m is not None
        return np.asarray(np.linalg.norm(p - data.p_world_m, axis=1), dtype=np.float64)
    assert data.group is not None
    ids = np.asarray(result.problem.group_ids)
    unknown = sorted(set(data.groups()) - set(ids.tolist()))
    if unknown:
        raise UsageError(f"validation poses touch groups {unknown} that no training pose touched")
    P = result.problem.points_of(result.theta)
    return np.asarray(np.linalg.norm(p - P[np.searchsorted(ids, data.group)], axis=1), dtype=np.float64)
