"""workflows.kinematics.fit on the simulated SO-101: the done-when numbers of issue 13 (held-out poses)."""

from __future__ import annotations

import numpy as np
import pytest

from robocal.backends.sim.kinematic_arm import SimulatedKinematicArm, hidden_errors
from robocal.core.kinematic_errors import ErrorModel
from robocal.core.kinematic_problem import Measurements, Problem, free_indices, plan_poses
from robocal.errors import UsageError
from robocal.workflows.kinematics.fit import PriorSigmas, fit, split_validation, validation_errors

from .conftest import so101_model

MODEL = so101_model()
FREE = free_indices(MODEL, ["base"])
CANDIDATES = SimulatedKinematicArm(MODEL, np.zeros(MODEL.n_params)).sample_q(2000, np.random.default_rng(99))


def _arm(seed: int, ticks: int = 4096) -> tuple[SimulatedKinematicArm, np.random.Generator]:
    rng = np.random.default_rng(seed)
    return SimulatedKinematicArm(MODEL, hidden_errors(MODEL, rng), ticks_per_turn=ticks), rng


def _measure(
    arm: SimulatedKinematicArm, q_true: np.ndarray, noise_m: float, rng: np.random.Generator
) -> Measurements:
    truth = arm.true_points(q_true)
    return Measurements("points", arm.read(q_true), truth + rng.normal(0.0, noise_m, truth.shape))


def _held_out_errors(
    arm: SimulatedKinematicArm, x: np.ndarray, rng: np.random.Generator, model: ErrorModel = MODEL
):
    q = arm.sample_q(200, rng)
    truth = arm.true_points(q)
    return (
        np.linalg.norm(model.points(arm.read(q), x) - truth, axis=1),
        np.linalg.norm(model.points(arm.read(q)) - truth, axis=1),
    )


def test_noise_free_recovers_tool_points_below_a_micrometre() -> None:
    arm, rng = _arm(1, ticks=0)
    data, _ = arm.measure_points(100, 0.0, rng)
    result = fit(Problem(MODEL, data, FREE, np.zeros(MODEL.n_params)))
    assert result.identifiability.rank == 23
    err, nominal = _held_out_errors(arm, result.x, rng)
    assert err.max() < 1e-6
    assert 5e-3 < nominal.mean() < 30e-3
    assert result.method == "lm" and result.success


@pytest.mark.slow
def test_50_selected_poses_half_mm_noise_4096_ticks() -> None:
    """Averaged over six draws of the hidden errors (single draws scatter by about ±0.05 mm)."""
    q = CANDIDATES[plan_poses(MODEL, CANDIDATES, 50, criterion="I")]
    means, maxima, nominals = [], [], []
    for seed in range(6):
        arm, rng = _arm(seed)
        result = fit(Problem(MODEL, _measure(arm, q, 0.5e-3, rng), FREE, np.zeros(MODEL.n_params)))
        err, nominal = _held_out_errors(arm, result.x, rng)
        means.append(err.mean())
        maxima.append(err.max())
        nominals.append(nominal.mean())
        # the fit's own noise estimate is the marker noise (0.5 mm per axis)
        rms = float(np.sqrt(np.mean(result.train_errors_m**2) / 3.0))
        assert 0.3e-3 < rms < 0.6e-3
        sigma_offset = result.sigma[result.problem.names.index("shoulder_lift.offset")]
        assert 0.0 < sigma_offset < np.radians(0.5)
    assert np.mean(nominals) > 10e-3
    assert np.mean(means) <= 0.4e-3
    assert np.mean(maxima) <= 0.9e-3
    assert max(means) < 0.5e-3


@pytest.mark.slow
def test_20_selected_poses_mean_below_0_8_mm() -> None:
    q = CANDIDATES[plan_poses(MODEL, CANDIDATES, 20, criterion="I")]
    means = []
    for seed in range(6):
        arm, rng = _arm(seed)
        result = fit(Problem(MODEL, _measure(arm, q, 0.5e-3, rng), FREE, np.zeros(MODEL.n_params)))
        means.append(_held_out_errors(arm, result.x, rng)[0].mean())
    assert np.mean(means) <= 0.8e-3


def test_too_few_poses_is_refused() -> None:
    arm, rng = _arm(3)
    data, _ = arm.measure_points(7, 0.5e-3, rng)
    with pytest.raises(
        UsageError,
        match=r"too few poses: 7 poses give 21 equations, not more than the 21 parameters they could identify \(the model has 23\); record at least 9 poses",
    ):
        fit(Problem(MODEL, data, FREE, np.zeros(MODEL.n_params)))


def test_huber_loss_resists_outliers() -> None:
    arm, rng = _arm(4)
    data, _ = arm.measure_points(60, 0.2e-3, rng)
    p = data.p_world_m.copy()
    p[[3, 17, 40]] += [0.03, -0.02, 0.025]  # three marker dropouts, 2-3 cm off
    bad = Measurements("points", data.q_rad, p)
    plain = fit(Problem(MODEL, bad, FREE, np.zeros(MODEL.n_params)))
    robust = fit(Problem(MODEL, bad, FREE, np.zeros(MODEL.n_params)), huber_m=1e-3)
    e_plain, _ = _held_out_errors(arm, plain.x, rng)
    e_robust, _ = _held_out_errors(arm, robust.x, rng)
    assert robust.method == "trf" and robust.loss == "huber"
    assert e_robust.mean() < 0.5e-3 < e_plain.mean()


def test_prior_keeps_a_short_session_near_nominal() -> None:
    arm, rng = _arm(5)
    data, _ = arm.measure_points(12, 0.5e-3, rng)
    free_fit = fit(Problem(MODEL, data, FREE, np.zeros(MODEL.n_params)))
    prior_fit = fit(Problem(MODEL, data, FREE, np.zeros(MODEL.n_params)), prior=PriorSigmas())
    assert prior_fit.method == "lm"
    assert np.linalg.norm(prior_fit.x) < np.linalg.norm(free_fit.x)
    # with the prior every parameter is estimated (the prior decides what the data cannot see) ...
    names = prior_fit.problem.names
    rz = names.index("shoulder_pan.rz")  # the same as shoulder_pan's offset: not in the base set
    assert rz not in prior_fit.identifiability.base
    assert np.isnan(free_fit.sigma[rz]) and free_fit.theta[rz] == 0.0
    assert 0.0 < prior_fit.sigma[rz] < np.radians(0.5) and prior_fit.theta[rz] != 0.0
    # ... and the posterior is tighter than the prior (2° for an offset), though wider than the base-set σ: the
    # offset now shares what the data sees with the rotations it cannot be told apart from
    lift = names.index("shoulder_lift.offset")
    assert free_fit.sigma[lift] < prior_fit.sigma[lift] < np.radians(2.0)
    # the posterior over the estimated unknowns is square and symmetric
    k = int(np.sum(np.isfinite(prior_fit.sigma)))
    assert k == len(FREE) and prior_fit.covariance.shape == (k, k)
    assert np.allclose(prior_fit.covariance, prior_fit.covariance.T)


def test_prior_noise_is_estimated_or_given() -> None:
    arm, rng = _arm(7)
    data, _ = arm.measure_points(50, 0.5e-3, rng)
    problem = Problem(MODEL, data, FREE, np.zeros(MODEL.n_params))
    estimated = fit(problem, prior=PriorSigmas())
    # a far too small stated noise lets the data win: the result is the fit without the prior
    data_only = fit(problem, prior=PriorSigmas(noise_m=1e-9))
    plain = fit(problem)
    assert np.max(np.abs(problem.model.points(data.q_rad, data_only.x) - problem.model.points(data.q_rad, plain.x))) < 1e-7
    # a far too large one gives the prior all the weight: nothing moves from nominal
    prior_only = fit(problem, prior=PriorSigmas(noise_m=1.0))
    assert np.max(np.abs(prior_only.x)) < 1e-4
    # the estimated noise (the marker's 0.5 mm) lies between the two: the result moves a little towards nominal
    est_dev = np.linalg.norm(estimated.x - plain.x)
    assert 0.0 < est_dev < np.linalg.norm(plain.x)


@pytest.mark.parametrize(
    "kwargs, message",
    [
        ({"length_m": 0.0}, "prior length_m: must be a positive number, got 0.0"),
        ({"angle_rad": float("nan")}, "prior angle_rad: must be a positive number, got nan"),
        ({"offset_rad": -1.0}, "prior offset_rad: must be a positive number, got -1.0"),
        ({"noise_m": float("inf")}, "prior noise: must be a positive number, got inf"),
    ],
)
def test_prior_sigmas_are_checked(kwargs: dict, message: str) -> None:
    with pytest.raises(UsageError, match=message):
        PriorSigmas(**kwargs)


def test_split_and_validation_on_points() -> None:
    arm, rng = _arm(6)
    data, _ = arm.measure_points(40, 0.0, rng)
    train, val = split_validation(data, 0.25, seed=1)
    assert len(val) == 10 and len(train) == 30 and not set(train) & set(val)
    result = fit(Problem(MODEL, data.subset(train), FREE, np.zeros(MODEL.n_params)))
    assert validation_errors(result, data.subset(val)).max() < 2e-3  # quantisation only
    with pytest.raises(UsageError, match="validate-fraction"):
        split_validation(data, 1.0)
    with pytest.raises(
        UsageError, match=r"--validate-fraction 0.99 holds out 40 of 40 poses and leaves 0 to fit"
    ):
        split_validation(data, 0.99)


@pytest.mark.slow
def test_touch_and_gauge_sessions() -> None:
    arm, rng = _arm(8, ticks=0)
    gauge = arm.gauge([0.2, 0.0, 0.05], 0.05, 15, rng)
    touch = Measurements("touch", gauge.q_rad, group=gauge.group)
    g = fit(Problem(MODEL, gauge, FREE, np.zeros(MODEL.n_params)))
    t = fit(Problem(MODEL, touch, FREE, np.zeros(MODEL.n_params)))
    assert g.identifiability.rank == t.identifiability.rank + 1  # the known distance fixes the scale
    reasons = {u.name: u.reason for u in t.identifiability.unidentifiable}
    assert any(r.startswith("touch data does not show the arm's overall size") for r in reasons.values())
    sockets = g.problem.points_of(g.theta)
    assert np.linalg.norm(sockets[1] - sockets[0]) == pytest.approx(0.05, abs=1e-9)
    # up to a rigid motion (touch data has no outside frame) the gauge fit reproduces the true arm
    q = arm.sample_q(100, rng)
    a, b = MODEL.points(q, g.x), arm.true_points(q)
    a0, b0 = a - a.mean(0), b - b.mean(0)
    U, _, Vt = np.linalg.svd(a0.T @ b0)
    R = (U @ Vt).T
    assert np.linalg.norm((R @ a0.T).T - b0, axis=1).max() < 1e-6


@pytest.mark.slow
def test_accuracy_bars_per_draw_over_twenty_seeds() -> None:
    """Issue 13's bars checked per draw of the hidden errors (seeds 0-19), not only on average.

    The poses are what ``robocal kinematics plan`` chooses by default: greedy I-optimal (the smallest average
    prediction variance of the tool point over the 2000 candidates). Measured, 50 poses, plain fit of the base
    set: mean 0.27-0.444 mm (average 0.350), max up to 0.987 (average 0.806); 1 draw over 0.4 mm mean and 3 over
    0.9 mm max. With the tolerance prior (``PriorSigmas()``: 1 mm, 0.5°, 2°, the very distribution the hidden
    errors are drawn from): average 0.344 / 0.798, again 1 and 3 draws over. The greedy D-optimal (O1) plan of
    before, on the same draws: average 0.365 / 0.828, 5 and 8 draws over (prior: 0.352 / 0.804, 4 and 7).
    20 I-optimal poses: mean 0.41-0.63 mm (average 0.517; prior 0.493). So "20 poses: mean <= 0.8" holds for
    every draw; "50 poses: mean <= 0.4 and max <= 0.9" does not for every single one. The held-out readings' own
    4096-tick quantisation already costs 0.19 mm mean / 0.53 mm max; the parameters' part is about 0.29 / 0.61
    (information-bound: 150 equations at 0.5 mm for 23 identifiable parameters). A Bayesian I-optimal plan,
    8000 candidates, weighting by the joint quantisation and poses above the table were measured too: none
    lowers the misses further (with 8000 candidates the max misses scatter between 3 and 7 from plan to plan).
    """
    q50 = CANDIDATES[plan_poses(MODEL, CANDIDATES, 50, criterion="I")]
    q20 = CANDIDATES[plan_poses(MODEL, CANDIDATES, 20, criterion="I")]
    d50 = CANDIDATES[plan_poses(MODEL, CANDIDATES, 50, criterion="D")]
    stats: dict[tuple[str, bool], tuple[list[float], list[float]]] = {
        (n, p): ([], []) for n in ("I50", "I20", "D50") for p in (False, True)
    }
    for seed in range(20):
        for label, q in (("I50", q50), ("I20", q20), ("D50", d50)):
            arm, rng = _arm(seed)
            problem = Problem(MODEL, _measure(arm, q, 0.5e-3, rng), FREE, np.zeros(MODEL.n_params))
            val_state = rng.bit_generator.state
            for use_prior in (False, True):
                rng.bit_generator.state = val_state  # the same held-out poses for both fits
                result = fit(problem, prior=PriorSigmas() if use_prior else None)
                err = _held_out_errors(arm, result.x, rng)[0]
                stats[label, use_prior][0].append(err.mean())
                stats[label, use_prior][1].append(err.max())
    m50, x50 = (np.array(v) for v in stats["I50", False])
    p50, px50 = (np.array(v) for v in stats["I50", True])
    dm50, dx50 = (np.array(v) for v in stats["D50", False])
    m20 = np.array(stats["I20", False][0])
    assert m50.mean() <= 0.36e-3 and x50.mean() <= 0.82e-3
    assert m50.max() <= 0.46e-3 and x50.max() <= 1.0e-3
    # the per-draw bars are missed by a few draws (measured 1 and 3; ±1 for another BLAS)
    assert np.sum(m50 > 0.4e-3) <= 2 and 2 <= np.sum(x50 > 0.9e-3) <= 4
    assert np.sum(p50 > 0.4e-3) <= 2 and 2 <= np.sum(px50 > 0.9e-3) <= 4
    # the I-optimal plan beats the D-optimal one on the same draws (measured 0.350 / 0.806 against 0.365 / 0.828)
    assert m50.mean() < dm50.mean() - 0.008e-3 and x50.mean() < dx50.mean() - 0.01e-3
    assert np.sum(m50 > 0.4e-3) < np.sum(dm50 > 0.4e-3) and np.sum(x50 > 0.9e-3) < np.sum(dx50 > 0.9e-3)
    # the prior helps a little on average
    assert p50.mean() < m50.mean() - 0.003e-3 and px50.mean() < x50.mean()
    assert m20.max() <= 0.8e-3 and np.array(stats["I20", True][0]).max() <= 0.8e-3
