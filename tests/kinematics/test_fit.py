"""workflows.kinematic_fit on the simulated SO-101: the done-when numbers of issue 13 (held-out poses)."""

from __future__ import annotations

import numpy as np
import pytest

from robocal.backends.sim.kinematic_arm import SimulatedKinematicArm, hidden_errors
from robocal.core.kinematic_errors import ErrorModel
from robocal.core.kinematic_problem import Measurements, Problem, free_indices, plan_poses
from robocal.errors import UsageError
from robocal.workflows.kinematic_fit import PriorSigmas, fit, split_validation, validation_errors

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


def test_50_selected_poses_half_mm_noise_4096_ticks() -> None:
    """Averaged over six draws of the hidden errors (single draws scatter by about ±0.05 mm)."""
    q = CANDIDATES[plan_poses(MODEL, CANDIDATES, 50)]
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


def test_20_selected_poses_mean_below_0_8_mm() -> None:
    q = CANDIDATES[plan_poses(MODEL, CANDIDATES, 20)]
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
    assert prior_fit.method == "trf"
    assert np.linalg.norm(prior_fit.x) < np.linalg.norm(free_fit.x)


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


def test_accuracy_bars_per_draw_over_twenty_seeds() -> None:
    """Issue 13's bars checked per draw of the hidden errors (seeds 0-19), not only on average.

    Measured (greedy O1 selection of 50 / 20 of 2000 candidates): 50 poses, mean 0.275-0.439 mm (average
    0.365), max 0.61-0.98 mm (average 0.83); 20 poses, mean 0.41-0.69 mm. The averaged bars (mean <= 0.4, max
    <= 0.9) and "20 poses: mean <= 0.8" hold for every draw; "50 poses: mean <= 0.4 and max <= 0.9" does not
    hold for every single draw (5 draws exceed 0.4 mm mean, 7 exceed 0.9 mm max). The held-out readings' own
    4096-tick quantisation already costs 0.19 mm mean / 0.51 mm max; an I-optimal selection (average prediction
    variance) and 10000 candidates were measured too and did not change this.
    """
    q50 = CANDIDATES[plan_poses(MODEL, CANDIDATES, 50)]
    q20 = CANDIDATES[plan_poses(MODEL, CANDIDATES, 20)]
    m50, x50, m20 = [], [], []
    for seed in range(20):
        for q, means, maxima in ((q50, m50, x50), (q20, m20, None)):
            arm, rng = _arm(seed)
            result = fit(Problem(MODEL, _measure(arm, q, 0.5e-3, rng), FREE, np.zeros(MODEL.n_params)))
            err = _held_out_errors(arm, result.x, rng)[0]
            means.append(err.mean())
            if maxima is not None:
                maxima.append(err.max())
    assert np.mean(m50) <= 0.4e-3 and np.mean(x50) <= 0.9e-3
    assert max(m50) <= 0.45e-3 and max(x50) <= 1.0e-3
    assert 3 <= sum(m > 0.4e-3 for m in m50) <= 8  # the per-draw mean bar is missed by a few draws
    assert max(m20) <= 0.8e-3
