"""core.identifiability and core.kinematic_problem.analyse: rank, base set, reasons, observability, selection."""

from __future__ import annotations

import math

import numpy as np
import pytest

from robocal.core.identifiability import analyse_columns, observability, pivoted_qr_order, select_poses
from robocal.core.kinematic_problem import Measurements, Problem, analyse, free_indices

from .conftest import MARKER_ON_AXIS_M, so101_model


def _problem(marker=None, n=60, seed=0, still=None):  # type: ignore[no-untyped-def]
    model = so101_model() if marker is None else so101_model(marker)
    rng = np.random.default_rng(seed)
    lo, up = model.chain.limits()
    q = rng.uniform(lo + 0.05, up - 0.05, (n, 5))
    if still is not None:
        q[:, still] = 0.25
    data = Measurements("points", q, model.points(q))
    return Problem(model, data, free_indices(model, ["base"]), np.zeros(model.n_params))


def test_rank_23_off_axis_with_offsets_in_the_base_set() -> None:
    ident = analyse(_problem())
    assert ident.rank == 23
    assert len(ident.unidentifiable) == 41 - 23
    assert {
        "shoulder_pan.offset",
        "shoulder_lift.offset",
        "elbow_flex.offset",
        "wrist_flex.offset",
        "wrist_roll.offset",
        "tool.x",
    } <= set(ident.base_names)
    reasons = {u.name: u.reason for u in ident.unidentifiable}
    assert reasons["tool.rx"].startswith("a measured point does not show the tool's orientation")
    assert reasons["shoulder_pan.rz"] == (
        "a rotation about shoulder_pan's own axis is the same as its zero offset (shoulder_pan.offset)"
    )
    assert ident.observability.condition < 1e4
    listed = [u.name for u in ident.unidentifiable]  # in the model's parameter order, not the pivot order
    assert listed == sorted(listed, key=ident.names.index)
    assert listed[:4] == ["shoulder_pan.rz", "shoulder_lift.z", "shoulder_lift.rx", "shoulder_lift.rz"]


def test_unidentifiable_list_does_not_follow_rounding_noise() -> None:
    # Six independent columns (preferred for the base set) and six that repeat them (scaled, or a sum of two): the
    # pivoted QR's tail order is decided by remainders of ~1e-16, so a change in the last bits must not reorder
    # the list.
    rng = np.random.default_rng(3)
    free = rng.normal(size=(40, 6))
    J = np.column_stack([free, 2.0 * free[:, 0], free[:, 1] + free[:, 2], -free[:, 3], 0.5 * free[:, 4],
                         free[:, 5] - free[:, 0], 3.0 * free[:, 2]])  # fmt: skip
    names = [f"p{i}" for i in range(12)]
    lists = set()
    for seed in range(8):
        noise = np.random.default_rng(seed).normal(size=J.shape) * 1e-15
        ident = analyse_columns(J + noise, names, priority=[0] * 6 + [1] * 6)
        assert ident.rank == 6
        lists.add(tuple(u.name for u in ident.unidentifiable))
    assert len(lists) == 1
    assert lists == {("p6", "p7", "p8", "p9", "p10", "p11")}


def test_marker_on_wrist_roll_axis_is_named() -> None:
    ident = analyse(_problem(MARKER_ON_AXIS_M))
    assert ident.rank == 21
    reasons = {u.name: u.reason for u in ident.unidentifiable}
    assert "wrist_roll.offset" not in ident.base_names
    assert reasons["wrist_roll.offset"].startswith(
        "the marker is on the wrist_roll axis, so turning wrist_roll does not move it; move the marker off"
    )


def test_joint_that_never_moved_is_named() -> None:
    ident = analyse(_problem(still=3))
    reasons = {u.name: u.reason for u in ident.unidentifiable}
    assert ident.rank < 23
    hits = [
        n for n, r in reasons.items() if r.startswith("wrist_flex did not move in the poses (always 0.25)")
    ]
    assert hits


def test_pivoted_qr_prefers_by_priority_among_equal_columns() -> None:
    a = np.array([[1.0, 0.0], [0.0, 1.0], [0.0, 0.0]])
    A = np.column_stack([a[:, 0], a[:, 1], a[:, 0]])  # column 2 duplicates column 0
    assert pivoted_qr_order(A, [1, 1, 0])[:2].tolist() in ([2, 1], [1, 2])
    assert 0 not in pivoted_qr_order(A, [1, 1, 0])[:2].tolist()
    ident = analyse_columns(A, ["a", "b", "c"], priority=[1, 1, 0])
    assert ident.rank == 2
    assert ident.unidentifiable[0].name == "a"
    assert ident.unidentifiable[0].same_as == (("c", pytest.approx(1.0)),)


def test_zero_column_is_reported() -> None:
    A = np.array([[1.0, 0.0], [2.0, 0.0]])
    ident = analyse_columns(A, ["a", "b"])
    assert ident.rank == 1
    assert ident.unidentifiable[0].reason == "does not change the measurements at all"


def test_observability_indices_of_a_known_matrix() -> None:
    J = np.diag([4.0, 2.0, 1.0])
    J = np.vstack([J, np.zeros((1, 3))])  # 4 rows; columns already unit-norm after scaling
    obs = observability(J * np.array([1.0, 1.0, 1.0]))
    # columns scaled to unit norm: identity, all σ = 1
    assert obs.condition == pytest.approx(1.0)
    assert pytest.approx(1.0 / math.sqrt(4)) == obs.O1
    B = np.array([[1.0, 1.0], [0.0, 1e-3]])
    obs2 = observability(B)
    sv = np.linalg.svd(B / np.linalg.norm(B, axis=0), compute_uv=False)
    assert obs2.condition == pytest.approx(sv[0] / sv[1])
    assert pytest.approx(sv[1]) == obs2.O3
    assert pytest.approx(sv[1] ** 2 / sv[0]) == obs2.O5


@pytest.mark.slow
def test_greedy_selection_beats_random_poses() -> None:
    pr = _problem(n=1500, seed=5)
    ident = analyse(pr)
    _, J = pr.residuals_and_jacobian(pr.initial_theta())
    cols = list(ident.base)
    Jc = (J[:, cols] / ident.column_norms[cols]).reshape(1500, 3, -1)
    chosen = select_poses(Jc, 30)
    assert len(set(chosen.tolist())) == 30
    A_sel = Jc[chosen].reshape(-1, len(cols))
    A_rand = Jc[:30].reshape(-1, len(cols))
    gain = np.linalg.slogdet(A_sel.T @ A_sel)[1] - np.linalg.slogdet(A_rand.T @ A_rand)[1]
    assert gain > 5.0  # det(JᵀJ) over e^5 times larger than for the first 30 random poses
    assert observability(A_sel).condition < observability(A_rand).condition
