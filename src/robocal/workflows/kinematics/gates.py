"""Plausibility gates of ``kinematics identify``: what must hold before a number is claimed.

* **Distinct poses.** Rows that repeat another row exactly (the same readings and the same measurement) are one
  measurement, kept once. Poses are told apart at the encoder resolution (``--ticks``, default 4096 per turn):
  readings on the same tick of every joint are one pose, however many rows measure it. The fitted poses must be
  more than the parameters the model can identify (:func:`check_distinct_poses`).
* **Identifiability.** The data's rank must reach the rank the same model has with well spread poses of the same
  kind (:func:`structural_analysis`); below it the parameters the poses leave unseen are named
  (:func:`check_rank`).
* **Held-out poses** that repeat fitted poses are not a validation (:func:`held_out_repeats`).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np

from ...core.arrays import FloatArray, IntArray
from ...core.chain import SerialChain
from ...core.identifiability import Identifiability
from ...core.kinematic_problem import Measurements, Problem, analyse
from ...errors import UsageError
from .fit import split_validation

__all__ = [
    "DEFAULT_TICKS_PER_TURN",
    "MAX_DISTINCT_ROWS",
    "PRISMATIC_RESOLUTION_M",
    "HeldOut",
    "PoseCells",
    "Sessions",
    "check_distinct_poses",
    "check_rank",
    "check_ticks",
    "distinct_poses",
    "held_out_repeats",
    "pose_cells",
    "sessions",
    "structural_analysis",
]

DEFAULT_TICKS_PER_TURN = 4096
"""Encoder resolution poses are told apart at (12-bit servos: SO-101, Koch); ``--ticks``."""

PRISMATIC_RESOLUTION_M = 1e-5
"""Resolution prismatic joints are told apart at (10 µm)."""

MAX_DISTINCT_ROWS = 20_000
"""Most rows (after exact copies are merged) ``identify`` fits: 3 residuals × ~50 unknowns × 8 bytes each keeps
the Jacobian under 25 MB and the fit within seconds; a longer session is refused with advice to thin it."""

STRUCTURAL_POSES = 60
"""Spread configurations the model's own rank is computed from (the same seed every run)."""


def check_ticks(ticks_per_turn: int) -> int:
    """``--ticks`` as given, checked (0: readings are exact, any difference makes another pose).

    Raises:
        UsageError: Negative.
    """
    if ticks_per_turn < 0:
        raise UsageError(f"--ticks must be 0 (exact readings) or a number of ticks per turn, got {ticks_per_turn}")
    return ticks_per_turn


@dataclass(frozen=True, eq=False)
class PoseCells:
    """Rows of a session grouped into distinct poses.

    Attributes:
        kept: ``(M,)`` rows kept, in file order (an exact copy of an earlier row is left out).
        pose: ``(M,)`` distinct-pose index of each kept row (poses numbered by first appearance).
        first: ``(P,)`` the first kept row (index into ``kept``) of each distinct pose.
        cells: ``(P, n_q)`` the encoder cell of each distinct pose (integer ticks; the readings when exact).
        copies: Rows left out as exact copies.
    """

    kept: IntArray
    pose: IntArray
    first: IntArray
    cells: FloatArray
    copies: int

    @property
    def n_poses(self) -> int:
        """Number of distinct poses."""
        return int(self.cells.shape[0])


def _resolution(chain: SerialChain, ticks_per_turn: int) -> FloatArray:
    if ticks_per_turn == 0:
        return np.zeros(chain.n_q)
    return np.array(
        [PRISMATIC_RESOLUTION_M if j.type == "prismatic" else 2.0 * math.pi / ticks_per_turn for j in chain.movable]
    )


def _cells(q_rad: FloatArray, resolution: FloatArray) -> FloatArray:
    safe = np.where(resolution > 0.0, resolution, 1.0)
    return np.where(resolution > 0.0, np.round(q_rad / safe), q_rad)


def _first_order(values: FloatArray) -> tuple[IntArray, IntArray]:
    """Unique rows of ``values`` numbered by first appearance: (first row of each, index of each row)."""
    _, first, inverse = np.unique(values, axis=0, return_index=True, return_inverse=True)
    inverse = inverse.reshape(-1)
    order = np.argsort(first, kind="stable")
    renumber = np.empty_like(order)
    renumber[order] = np.arange(order.size)
    return first[order], renumber[inverse]


def distinct_poses(q_rad: FloatArray, chain: SerialChain, ticks_per_turn: int) -> tuple[IntArray, IntArray]:
    """The distinct poses of joint readings at the encoder resolution, numbered by first appearance.

    Returns:
        ``(P,)`` the first row of each distinct pose and ``(N,)`` the distinct pose of each row.
    """
    if not q_rad.shape[0]:
        return np.zeros(0, dtype=np.int64), np.zeros(0, dtype=np.int64)
    first, pose = _first_order(_cells(q_rad, _resolution(chain, ticks_per_turn)))
    return first.astype(np.int64), pose.astype(np.int64)


def pose_cells(data: Measurements, chain: SerialChain, ticks_per_turn: int, *, source: str) -> PoseCells:
    """Exact copies merged, then the distinct poses at the encoder resolution.

    Raises:
        UsageError: More than :data:`MAX_DISTINCT_ROWS` rows remain.
    """
    cols = [data.q_rad]
    if data.p_world_m is not None:
        cols.append(data.p_world_m)
    if data.group is not None:
        cols.append(data.group[:, None].astype(np.float64))
    rows = np.column_stack(cols) if data.n_poses else np.zeros((0, len(cols)))
    if data.n_poses:
        kept, _ = _first_order(rows)
        kept = np.sort(kept)
    else:
        kept = np.zeros(0, dtype=np.int64)
    if kept.size > MAX_DISTINCT_ROWS:
        raise UsageError(
            f"{source}: {kept.size} different rows; identify fits at most {MAX_DISTINCT_ROWS} (memory and time): "
            "thin the session (a few hundred spread poses identify an arm as well as more)"
        )
    cells = _cells(data.q_rad[kept], _resolution(chain, ticks_per_turn))
    if kept.size:
        first, pose = _first_order(cells)
    else:
        first, pose = np.zeros(0, dtype=np.int64), np.zeros(0, dtype=np.int64)
    return PoseCells(
        kept.astype(np.int64), pose.astype(np.int64), first.astype(np.int64), cells[first],
        data.n_poses - int(kept.size),
    )  # fmt: skip


def held_out_repeats(fitted: PoseCells, held_out: PoseCells) -> IntArray:
    """Rows of ``held_out.kept`` (indices into it) whose pose is one of the fitted poses."""
    seen = {tuple(c) for c in fitted.cells.tolist()}
    return np.array(
        [k for k, p in enumerate(held_out.pose) if tuple(held_out.cells[p].tolist()) in seen], dtype=np.int64
    )


def structural_analysis(problem: Problem, tolerance: float = 1e-8) -> Identifiability:
    """The identifiability the problem's model has with well spread poses of the same kind.

    :data:`STRUCTURAL_POSES` seeded configurations inside the limits; point data at the nominal points, contact
    data spread over the session's contact groups. The data can reach this rank, never more.
    """
    model = problem.model
    lo, up = model.chain.limits()
    lo = np.where(np.isfinite(lo), lo, -math.pi)
    up = np.where(np.isfinite(up), up, math.pi)
    q = np.random.default_rng(0).uniform(lo, up, (STRUCTURAL_POSES, lo.size))
    kind = problem.data.kind
    if kind == "points":
        spread = Measurements("points", q, model.points(q, problem.x_fixed))
    else:
        ids = np.asarray(problem.group_ids, dtype=np.int64)
        spread = Measurements(kind, q, group=ids[np.arange(q.shape[0]) % ids.size], distance_m=problem.data.distance_m)
    return analyse(Problem(model, spread, problem.free, problem.x_fixed), tolerance=tolerance)


def check_distinct_poses(
    cells: PoseCells, structural_rank: int, *, rows: int, source: str, fitted: bool = False
) -> None:
    """The poses must give more equations (3 per pose) than the parameters the model can identify.

    Args:
        cells: The session's (or its fitted share's) distinct poses.
        structural_rank: What the model can identify (:func:`structural_analysis`).
        rows: Rows these poses came from.
        source: The session file, for the message.
        fitted: ``cells`` are the fitted share (after the held-out poses were taken away).

    Raises:
        UsageError: Too few distinct poses (says how many rows repeat how many poses and how many to record).
    """
    need = structural_rank // 3 + 2
    n = cells.n_poses
    if n >= need:
        return
    repeats = "" if n == rows else f" ({rows} rows repeat {n} distinct {'pose' if n == 1 else 'poses'})"
    what = "distinct fitted" if fitted else "distinct"
    raise UsageError(
        f"too few poses: {source} has {n} {what} {'pose' if n == 1 else 'poses'}{repeats}, "
        f"{3 * n} equations for the {structural_rank} parameters this model can identify; record at least "
        f"{need} different poses (20 or more for a useful result; robocal kinematics plan chooses them)"
    )


def check_rank(data: Identifiability, structural: Identifiability) -> None:
    """Refuse data whose rank is below the model's, naming the parameters the poses leave unseen.

    Raises:
        UsageError: ``data.rank < structural.rank``.
    """
    if data.rank >= structural.rank:
        return
    always = {u.name for u in structural.unidentifiable}
    unseen = [u for u in data.unidentifiable if u.name not in always]
    by_reason: dict[str, list[str]] = {}
    for u in unseen:
        by_reason.setdefault(u.reason, []).append(u.name)
    # a joint that did not move is the cause the user can act on: first
    ordered = sorted(by_reason.items(), key=lambda item: "did not move" not in item[0])
    parts = [f"{', '.join(names)} ({reason})" for reason, names in ordered]
    raise UsageError(
        f"the poses identify {data.rank} of the {structural.rank} parameters this model can identify; "
        f"not identifiable from them: {'; '.join(parts)}; record poses that move every joint through its range "
        "(robocal kinematics plan chooses them)"
    )


@dataclass(frozen=True, eq=False)
class Sessions:
    """The fitted and held-out poses after the gates on distinct poses.

    Attributes:
        train: The poses to fit (exact copies merged).
        validation: The held-out poses (none that repeat a fitted pose).
        train_rows: ``(N,)`` the data row (0-based, in the file's order) of each fitted pose.
        structural: What the model can identify with well spread poses (:func:`structural_analysis`).
        report: The report's ``plausibility`` block so far (rows, copies, distinct poses, the model's rank).
        warnings: What the user should know (copies, held-out repeats, no validation).
    """

    train: Measurements
    validation: Measurements
    train_rows: IntArray
    structural: Identifiability
    report: dict[str, Any]
    warnings: tuple[str, ...]


@dataclass(frozen=True, eq=False)
class HeldOut:
    """Which poses are held out for validation: a separate session, or a seeded random share of the distinct ones.

    Attributes:
        fraction: Share of the distinct poses held out when ``session`` is None.
        seed: Seed of that split.
        session: A separate held-out session (``--validate-data``), or None to hold ``fraction`` out.
        source: Its file, for messages.
    """

    fraction: float
    seed: int = 0
    session: Measurements | None = None
    source: str | None = None


def sessions(
    data: Measurements,
    problem_of: Callable[[Measurements], Problem],
    chain: SerialChain,
    *,
    source: str,
    held_out: HeldOut,
    ticks_per_turn: int,
    check: Callable[[Measurements], None] = lambda _: None,
) -> Sessions:
    """Merge exact copies, count distinct poses, split or take the held-out poses, and check what the fit needs.

    Args:
        data: The session as read.
        problem_of: The identification problem of a set of poses (model, free parameters, nominal values).
        chain: The chain (its joint types set the resolution).
        source: The session file, for messages.
        held_out: The separate held-out session, or the share of the distinct poses to hold out.
        ticks_per_turn: Encoder resolution (0: exact readings).
        check: Judges the session once exact copies are merged (units, reach; see
            :mod:`robocal.workflows.kinematics.plausibility`), before anything else is computed from it.

    Raises:
        UsageError: Too few distinct poses (the session, or its fitted share), or a rank below the model's.
    """
    warnings: list[str] = []
    cells = pose_cells(data, chain, ticks_per_turn, source=source)
    if cells.copies:
        data = data.subset(cells.kept)
        warnings.append(
            f"{source}: {cells.copies} of {cells.copies + cells.kept.size} rows repeat an earlier row exactly (the "
            "same readings and the same measurement): each is counted once"
        )
    check(data)
    structural = structural_analysis(problem_of(data))
    check_distinct_poses(cells, structural.rank, rows=cells.copies + cells.kept.size, source=source)
    if held_out.session is None:
        # the distinct poses are split (each row its own when none repeats): rows of one pose stay on one side
        train_p, _ = split_validation(data.subset(cells.first), held_out.fraction, held_out.seed)
        in_train = np.isin(cells.pose, train_p)
        train, val = data.subset(np.flatnonzero(in_train)), data.subset(np.flatnonzero(~in_train))
        train_rows = cells.kept[in_train]
    else:
        train, val, train_rows = data, held_out.session, cells.kept
    train_cells = pose_cells(train, chain, ticks_per_turn, source=source)
    val_distinct = 0
    if val.n_poses:
        val_cells = pose_cells(val, chain, ticks_per_turn, source=held_out.source or source)
        repeats = held_out_repeats(train_cells, val_cells)
        keep = np.setdiff1d(np.arange(val_cells.kept.size), repeats)
        val_distinct = val_cells.n_poses - len({int(val_cells.pose[k]) for k in repeats})
        if repeats.size:
            val = val.subset(val_cells.kept[keep])
            these = "pose repeats a fitted pose" if repeats.size == 1 else "poses repeat fitted poses"
            warnings.append(
                f"{repeats.size} held-out {these} (the same encoder readings): left out of the validation"
            )
    if not val.n_poses:
        warnings.append(
            "not validated: no held-out pose differs from the fitted ones; hold some out (--validate-fraction) or "
            "record a separate session (--validate-data)"
        )
    problem = problem_of(train)
    check_distinct_poses(train_cells, structural.rank, rows=train.n_poses, source=source, fitted=True)
    check_rank(analyse(problem), structural)
    report = {
        "rows": cells.copies + cells.kept.size,
        "copies": cells.copies,
        "distinct_poses": {"fit": train_cells.n_poses, "validation": val_distinct},
        "ticks_per_turn": ticks_per_turn,
        "model_rank": structural.rank,
    }
    return Sessions(train, val, train_rows.astype(np.int64), structural, report, tuple(warnings))

