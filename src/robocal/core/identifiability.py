"""Which kinematic parameters a set of measurements can identify, and why the others cannot (pure numpy).

The identification Jacobian ``J`` (residual rows × parameter columns) is evaluated at the nominal model. Its
columns are scaled to unit norm first (metres and radians are not comparable); the rank comes from the SVD with
a relative tolerance; QR with column pivoting picks an identifiable *base set* of that many columns, preferring
columns in a given priority order when several are equally good. Every other column depends on the base set:
it is reported with the parameters it cannot be told apart from, in words a user can act on.

Observability of a pose set (Sun & Hollerbach's naming) on the scaled base-set columns of ``M`` rows:
``O1 = (σ_1 ⋯ σ_m)^(1/m) / √M``, the condition number ``σ_1 / σ_m`` (below ~100 is reliable), ``O3 = σ_m`` and
``O5 = σ_m² / σ_1``. :func:`select_poses` picks poses greedily, each maximising ``det(JᵀJ)`` (D-optimal, O1);
:func:`select_poses_i_optimal` each minimising the average prediction variance over a set of configurations
(I-optimal), optionally with a Gaussian prior on the parameters (Bayesian).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from ..errors import ShapeMismatchError, UsageError
from .arrays import BoolArray, FloatArray, IntArray
from .named import Named

__all__ = [
    "DEFAULT_RANK_TOLERANCE",
    "Explain",
    "Identifiability",
    "Observability",
    "UnidentifiableParameter",
    "analyse_columns",
    "common_reason",
    "observability",
    "pivoted_qr_order",
    "select_poses",
    "select_poses_i_optimal",
    "still_joints",
]


DEFAULT_RANK_TOLERANCE = 1e-8
"""Singular values below this fraction of the largest (of the column-scaled Jacobian) count as zero."""


@dataclass(frozen=True)
class Observability:
    """Quality indices of a pose set on the scaled base-set columns.

    Attributes:
        O1: Geometric mean of the singular values over √rows (larger is better).
        condition: ``σ_max / σ_min`` (below ~100 is reliable).
        O3: Smallest singular value.
        O5: ``σ_min² / σ_max``.
    """

    O1: float
    condition: float
    O3: float
    O5: float


@dataclass(frozen=True)
class UnidentifiableParameter:
    """A parameter the data cannot identify; it stays at its nominal value.

    Attributes:
        name: Parameter name.
        reason: Why, in user words, with what to do about it.
        same_as: The base-set parameters it moves the measurements like, ``(name, coefficient)``: a change of
            1 in this parameter equals a change of ``coefficient`` in each of these (units of each parameter).
    """

    name: str
    reason: str
    same_as: tuple[tuple[str, float], ...] = ()


@dataclass(frozen=True, eq=False)
class Identifiability:
    """The outcome of :func:`analyse_columns` plus the user-facing reasons.

    Attributes:
        names: Parameter names, one per Jacobian column.
        rank: Numerical rank of the scaled Jacobian.
        base: Indices of the identifiable base set, in pivot order.
        unidentifiable: One entry per other parameter, in the order of ``names`` (not the pivot order, whose
            tail is decided by rounding noise once the remaining columns are all but zero).
        singular_values: All singular values of the scaled Jacobian, descending.
        observability: Indices on the base-set columns.
        column_norms: Norms of the unscaled columns (the scaling).
    """

    names: tuple[str, ...]
    rank: int
    base: tuple[int, ...]
    unidentifiable: tuple[UnidentifiableParameter, ...]
    singular_values: FloatArray
    observability: Observability
    column_norms: FloatArray

    @property
    def base_names(self) -> tuple[str, ...]:
        """Names of the identifiable base set."""
        return tuple(self.names[i] for i in self.base)


def pivoted_qr_order(A: ArrayLike, priority: ArrayLike | None = None, *, usable: float = 0.05) -> IntArray:
    """Column order of a Householder QR with column pivoting (Businger–Golub), steered by a preference.

    At each step the columns whose remaining norm (the part not explained by the columns already taken) is at
    least ``usable`` times the largest remaining norm are candidates; among them the best ``priority`` tier wins
    and, inside it, the largest remaining norm. With ``usable = 1`` this is textbook pivoting; the default keeps
    the base set well conditioned while naming, say, joint offsets rather than the link lengths they trade with.

    Args:
        A: ``(m, n)`` matrix (scale its columns first).
        priority: ``(n,)`` preference, smaller first (default: all equal).
        usable: Relative remaining norm a column needs to be picked ahead of a larger one.

    Returns:
        ``(n,)`` permutation of the column indices.
    """
    R = np.array(A, dtype=np.float64)
    m, n = R.shape
    pri = np.zeros(n) if priority is None else np.asarray(priority, dtype=np.float64)
    perm = np.arange(n)
    for k in range(min(m, n)):
        norms = np.linalg.norm(R[k:, k:], axis=0)
        top = float(norms.max()) if norms.size else 0.0
        if top == 0.0:
            break
        if not math.isfinite(top):
            break
        cand = np.flatnonzero(norms >= usable * top)
        tier = pri[perm[k + cand]]
        cand = cand[tier == tier.min()]
        j = k + int(cand[np.argmax(norms[cand])])
        R[:, [k, j]] = R[:, [j, k]]
        perm[[k, j]] = perm[[j, k]]
        v = R[k:, k].copy()
        alpha = -math.copysign(float(np.linalg.norm(v)), v[0] if v[0] != 0 else 1.0)
        v[0] -= alpha
        vn = float(v @ v)
        if vn > 0.0 and math.isfinite(2.0 / vn):
            R[k:, k:] -= np.outer(v, (2.0 / vn) * (v @ R[k:, k:]))
    return perm


def _observability(sv: FloatArray, rows: int) -> Observability:
    if sv.size == 0 or sv[-1] <= 0.0:
        return Observability(0.0, math.inf, 0.0, 0.0)
    O1 = float(np.exp(np.mean(np.log(sv)))) / math.sqrt(max(rows, 1))
    return Observability(O1, float(sv[0] / sv[-1]), float(sv[-1]), float(sv[-1] ** 2 / sv[0]))


def observability(J: ArrayLike) -> Observability:
    """O1, condition number, O3 and O5 of a Jacobian (columns scaled to unit norm here).

    Args:
        J: ``(rows, k)`` Jacobian restricted to identifiable columns.
    """
    A = np.asarray(J, dtype=np.float64)
    norms = np.linalg.norm(A, axis=0)
    if np.any(norms == 0.0):
        return Observability(0.0, math.inf, 0.0, 0.0)
    sv = np.linalg.svd(A / norms, compute_uv=False)
    return _observability(sv, A.shape[0])


Explain = Callable[[int, tuple[tuple[str, float], ...], bool], str]
"""``explain(column, same_as, column_is_zero) -> reason`` for a dependent column."""


def analyse_columns(
    J: ArrayLike,
    names: Sequence[str],
    *,
    priority: ArrayLike | None = None,
    tolerance: float = DEFAULT_RANK_TOLERANCE,
    explain: Explain | None = None,
) -> Identifiability:
    """Rank, base set and dependencies of a stacked identification Jacobian.

    Args:
        J: ``(rows, P)`` Jacobian (all residuals stacked).
        names: ``P`` parameter names.
        priority: ``(P,)`` preference for the base set, smaller first.
        tolerance: Relative singular-value tolerance for the rank.
        explain: Turns a dependent column into a user-facing reason (default: a generic sentence).

    Returns:
        The :class:`Identifiability`.
    """
    A = np.asarray(J, dtype=np.float64)
    if A.ndim != 2 or A.shape[1] != len(names):
        raise ShapeMismatchError(f"Jacobian {A.shape} does not match {len(names)} parameter names")
    if not np.all(np.isfinite(A)):
        raise UsageError("identification Jacobian has NaN or infinite entries")
    norms = np.linalg.norm(A, axis=0)
    big = float(norms.max()) if norms.size else 0.0
    zero = norms <= 1e-12 * max(big, 1e-300)
    scaled = np.where(zero, 0.0, A / np.where(zero, 1.0, norms))
    sv = np.linalg.svd(scaled, compute_uv=False)
    rank = int(np.sum(sv > tolerance * sv[0])) if sv.size and sv[0] > 0 else 0
    order = pivoted_qr_order(scaled, priority)
    base = tuple(int(i) for i in order[:rank])
    B = scaled[:, list(base)]
    sv_base = np.linalg.svd(B, compute_uv=False) if rank else np.zeros(0)
    dependent = sorted(int(c) for c in order[rank:])  # in the order of names: the same list every run
    coefs = np.zeros((rank, len(dependent)))
    if rank and dependent:
        coefs = np.linalg.lstsq(B, scaled[:, dependent], rcond=None)[0]
    unident = []
    for d, c in enumerate(dependent):
        same: tuple[tuple[str, float], ...] = ()
        if not zero[c] and rank:
            coef = coefs[:, d]
            keep = np.flatnonzero(np.abs(coef) > 0.05)
            keep = keep[np.argsort(-np.abs(coef[keep]))]
            same = tuple((names[base[i]], float(coef[i] * norms[c] / norms[base[i]])) for i in keep)
        if explain is not None:
            reason = explain(c, same, bool(zero[c]))
        elif zero[c]:
            reason = "does not change the measurements at all"
        else:
            reason = "cannot be told apart from " + ", ".join(n for n, _ in same[:4])
        unident.append(UnidentifiableParameter(names[c], reason, same))
    return Identifiability(
        names=tuple(names),
        rank=rank,
        base=base,
        unidentifiable=tuple(unident),
        singular_values=sv,
        observability=_observability(sv_base, A.shape[0]),
        column_norms=norms,
    )


def still_joints(joints: Sequence[Named], q_rad: FloatArray) -> dict[str, float]:
    """Joints that kept one position over all poses: name → that position (rad or m).

    Args:
        joints: The movable joints, one per column of ``q_rad``.
        q_rad: Joint positions per pose, shape ``(N, len(joints))``.
    """
    return {
        j.name: float(q_rad[0, k])
        for k, j in enumerate(joints)
        if q_rad.shape[0] > 0 and float(np.ptp(q_rad[:, k])) < 1e-9
    }


def common_reason(
    group: str, kind: str, same: tuple[tuple[str, float], ...], is_zero: bool, measured: str
) -> str | None:
    """The reasons any measurement gives for an unidentifiable parameter ``group.kind``, or None.

    A parameter that changes nothing (``is_zero``), and a rotation about a joint's own axis that only
    duplicates that joint's zero offset. ``measured`` names what was measured ("measured points", "images").
    """
    if is_zero:
        return f"does not change the {measured} at all"
    if len(same) == 1:
        other = same[0][0]
        o_group, _, o_kind = other.partition(".")
        if o_group == group and o_kind == "offset" and kind.startswith("r"):
            return f"a rotation about {group}'s own axis is the same as its zero offset ({other})"
    return None


def _candidates(J_candidates: ArrayLike, n_select: int, regularisation: float) -> tuple[FloatArray, FloatArray]:
    """Checked candidate blocks ``(M, r, k)`` and the information ``εI`` a greedy selection starts from.

    Raises:
        ShapeMismatchError: The blocks are not 3-D.
        UsageError: ``n_select`` is not in ``1..M``.
    """
    Jc = np.asarray(J_candidates, dtype=np.float64)
    if Jc.ndim != 3:
        raise ShapeMismatchError(f"candidate Jacobians must be (M, rows, k), got {Jc.shape}")
    M, _, k = Jc.shape
    if not 0 < n_select <= M:
        raise UsageError(f"cannot select {n_select} poses from {M} candidates")
    eps = regularisation * float(np.mean(np.sum(Jc * Jc, axis=(0, 1)))) + 1e-300
    return Jc, eps * np.eye(k)


def _take(A: FloatArray, Jc: FloatArray, chosen: Sequence[int]) -> BoolArray:
    """Add the ``chosen`` candidates' information to ``A`` (in place); the mask of candidates still free."""
    for i in chosen:
        A += Jc[i].T @ Jc[i]
    available = np.ones(Jc.shape[0], dtype=bool)
    available[list(chosen)] = False
    return available


def _choose(A: FloatArray, Jc: FloatArray, gain: FloatArray, available: BoolArray, chosen: list[int]) -> None:
    """One greedy step: the free candidate of largest ``gain`` joins ``chosen``, its information ``A`` (in place)."""
    gain[~available] = -np.inf
    best = int(np.argmax(gain))
    chosen.append(best)
    available[best] = False
    A += Jc[best].T @ Jc[best]


def select_poses(
    J_candidates: ArrayLike,
    n_select: int,
    *,
    start: Sequence[int] = (),
    regularisation: float = 1e-9,
) -> IntArray:
    """Greedy D-optimal (O1) selection of poses from candidates.

    Each step adds the candidate that most increases ``log det(JᵀJ + εI)`` of the already selected rows,
    using ``det(A + JᵢᵀJᵢ) = det(A) · det(I + Jᵢ A⁻¹ Jᵢᵀ)``.

    Args:
        J_candidates: ``(M, r, k)`` Jacobian blocks per candidate pose (``r`` residuals, ``k`` identifiable
            columns, already scaled).
        n_select: How many poses to return (including ``start``).
        start: Indices selected beforehand.
        regularisation: ``ε``, relative to the mean squared column norm.

    Returns:
        ``(n_select,)`` candidate indices in the order chosen.
    """
    Jc, A = _candidates(J_candidates, n_select, regularisation)
    chosen = [int(i) for i in start]
    available = _take(A, Jc, chosen)
    while len(chosen) < n_select:
        Ainv = np.linalg.inv(A)
        S = np.einsum("mrk,kl,msl->mrs", Jc, Ainv, Jc)
        gain = np.linalg.slogdet(np.eye(S.shape[1]) + S)[1]
        _choose(A, Jc, gain, available, chosen)
    return np.asarray(chosen, dtype=np.int64)


def select_poses_i_optimal(
    J_candidates: ArrayLike,
    n_select: int,
    *,
    J_predict: ArrayLike | None = None,
    prior_precision: ArrayLike | None = None,
    start: Sequence[int] = (),
    regularisation: float = 1e-9,
) -> IntArray:
    """Greedy I-optimal selection of poses: the smallest average prediction variance.

    With ``A = P + Σ JᵢᵀJᵢ`` over the selected poses (``P`` the prior precision; ``J`` whitened by the
    measurement noise) the posterior covariance is ``A⁻¹`` and the average prediction variance over the
    prediction configurations ``trace(W A⁻¹)``, ``W = mean GₚᵀGₚ``. Each step adds the candidate that lowers
    it most; by Woodbury the drop for candidate ``i`` is ``trace((I + Jᵢ A⁻¹ Jᵢᵀ)⁻¹ Jᵢ A⁻¹ W A⁻¹ Jᵢᵀ)``.

    Args:
        J_candidates: ``(M, r, k)`` Jacobian blocks per candidate pose, divided by the measurement noise.
        n_select: How many poses to return (including ``start``).
        J_predict: ``(Mp, s, k)`` Jacobians of the predicted quantity (e.g. the tool point) at the
            configurations the model should predict well, in the same parameter units (default: the candidates).
        prior_precision: ``(k,)`` or ``(k, k)`` prior information ``P`` (``1/σ²`` per parameter, 0 for none);
            without it the first poses are D-optimal (:func:`select_poses`) until ``JᵀJ`` has full rank.
        start: Indices selected beforehand.
        regularisation: ``ε`` added to ``A``, relative to the mean squared column norm.

    Returns:
        ``(n_select,)`` candidate indices in the order chosen.
    """
    Jc, A = _candidates(J_candidates, n_select, regularisation)
    _, r, k = Jc.shape
    Jp = Jc if J_predict is None else np.asarray(J_predict, dtype=np.float64)
    if Jp.ndim != 3 or Jp.shape[2] != k:
        raise ShapeMismatchError(f"prediction Jacobians must be (M, rows, {k}), got {Jp.shape}")
    W = np.einsum("mrk,mrl->kl", Jp, Jp) / max(Jp.shape[0], 1)
    chosen = [int(i) for i in start]
    if prior_precision is None:
        n_d = min(n_select, max(len(chosen), -(-k // r) + 1))
        chosen = [int(i) for i in select_poses(Jc, n_d, start=chosen, regularisation=regularisation)]
    else:
        P = np.asarray(prior_precision, dtype=np.float64)
        A += np.diag(P) if P.ndim == 1 else P
    available = _take(A, Jc, chosen)
    eye = np.eye(r)
    while len(chosen) < n_select:
        Ainv = np.linalg.inv(A)
        JA = Jc @ Ainv  # (M, r, k)
        S = JA @ Jc.transpose(0, 2, 1)
        T = (JA @ W) @ JA.transpose(0, 2, 1)
        gain = np.einsum("mii->m", np.linalg.solve(eye + S, T))
        _choose(A, Jc, gain, available, chosen)
    return np.asarray(chosen, dtype=np.int64)
