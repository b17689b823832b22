"""Kinematic identification benchmark: 200 poses of the simulated SO-101 identified (analysis + LM fit).

Baselines measured in the same run: the same fit with scipy's finite-difference Jacobian instead of robocal's
analytic one, and the chain FK called pose by pose instead of batched.
"""

from __future__ import annotations

from importlib import resources

import numpy as np
from _timing import best_time

from robocal.backends.sim.kinematic_arm import SimulatedKinematicArm, hidden_errors
from robocal.core.chain import fk_chain
from robocal.core.kinematic_errors import ErrorModel
from robocal.core.kinematic_problem import Problem, analyse, free_indices
from robocal.formats.urdf import read_urdf
from robocal.formats.urdf_chain import chain_from_urdf
from robocal.workflows.kinematics.fit import fit


def _numeric_fit(problem: Problem) -> None:
    from scipy.optimize import least_squares

    theta0 = problem.initial_theta()
    base = list(analyse(problem, theta0).base)

    def fun(t_b: np.ndarray) -> np.ndarray:
        t = theta0.copy()
        t[base] = t_b
        return problem.residuals(t)

    least_squares(fun, theta0[base], method="lm", jac="2-point", xtol=1e-12, ftol=1e-12, gtol=1e-12)


def main() -> None:
    urdf = resources.files("robocal") / "data" / "so101_new_calib.urdf"
    chain = chain_from_urdf(read_urdf(str(urdf)), tip_link="gripper_link")
    T = np.eye(4)
    T[:3, 3] = [0.0121, 0.0, -0.0981]
    model = ErrorModel(chain, T_tip_tool=T)
    rng = np.random.default_rng(0)
    arm = SimulatedKinematicArm(model, hidden_errors(model, rng))
    data, truth = arm.measure_points(200, 0.5e-3, rng)
    problem = Problem(model, data, free_indices(model, ["base"]), np.zeros(model.n_params))
    fit(problem)  # warm-up (BLAS threads, imports)

    t_fit = best_time(lambda: fit(problem))
    result = fit(problem)
    t_num = best_time(lambda: _numeric_fit(problem), repeat=1)
    err = np.linalg.norm(model.points(data.q_rad, result.x) - truth, axis=1)
    print(
        f"identify 200 poses (rank {result.identifiability.rank}, analysis + LM, analytic Jacobian): "
        f"{t_fit * 1e3:.0f} ms  [target < 1000 ms]; error vs truth mean {err.mean() * 1e3:.3f} mm"
    )
    print(
        f"baseline: same fit with a finite-difference Jacobian: {t_num * 1e3:.0f} ms "
        f"(analytic ×{t_num / t_fit:.1f} faster)"
    )

    q = arm.sample_q(100_000, rng)
    t_batch = best_time(lambda: fk_chain(chain, q), repeat=2)
    t_loop = best_time(lambda: [fk_chain(chain, q[i]) for i in range(2000)], repeat=1) / 2000 * len(q)
    print(
        f"fk_chain, 100000 poses batched: {t_batch * 1e3:.0f} ms; pose by pose (timed on 2000): "
        f"{t_loop * 1e3:.0f} ms (×{t_loop / t_batch:.0f})"
    )
    t_jac = best_time(lambda: model.point_jacobian(data.q_rad, result.x))
    print(f"identification Jacobian, 200 poses × {model.n_params} parameters: {t_jac * 1e3:.2f} ms")
    _accuracy_per_seed(model)


def _accuracy_per_seed(model: ErrorModel, seeds: int = 20) -> None:
    """Issue 13's accuracy bars per draw of the hidden errors: 50 and 20 greedy I-optimal poses (what `kinematics plan` chooses), 0.5 mm noise, 4096 ticks."""
    from robocal.core.kinematic_problem import Measurements, plan_poses

    cand = SimulatedKinematicArm(model, np.zeros(model.n_params)).sample_q(2000, np.random.default_rng(99))
    free = free_indices(model, ["base"])
    from robocal.workflows.kinematics.fit import PriorSigmas

    for n, bar in ((50, "mean <= 0.4, max <= 0.9 mm"), (20, "mean <= 0.8 mm")):
        q = cand[plan_poses(model, cand, n, criterion="I")]
        for prior in (None, PriorSigmas()):
            means, maxima = [], []
            for seed in range(seeds):
                rng = np.random.default_rng(seed)
                arm = SimulatedKinematicArm(model, hidden_errors(model, rng))
                truth = arm.true_points(q)
                data = Measurements("points", arm.read(q), truth + rng.normal(0.0, 0.5e-3, truth.shape))
                res = fit(Problem(model, data, free, np.zeros(model.n_params)), prior=prior)
                qv = arm.sample_q(200, rng)
                e = np.linalg.norm(model.points(arm.read(qv), res.x) - arm.true_points(qv), axis=1) * 1e3
                means.append(e.mean())
                maxima.append(e.max())
            label = "--prior" if prior is not None else "plain"
            print(
                f"{n} poses, {label}, seeds 0-{seeds - 1} [{bar}]: mean {min(means):.3f}-{max(means):.3f} "
                f"(avg {np.mean(means):.3f}), max {min(maxima):.3f}-{max(maxima):.3f} (avg {np.mean(maxima):.3f}) mm; "
                f"draws over 0.4 mm mean: {sum(m > 0.4 for m in means)}, over 0.9 mm max: {sum(m > 0.9 for m in maxima)}"
            )
    _session_pipeline_per_seed(seeds)


def _session_pipeline_per_seed(seeds: int) -> None:
    """What `demo --identify` does, per draw: each draw plans its own 50 poses (`simulate`), 17 random held-out
    poses of a separate session (`--validation-poses`, `identify --validate-data`), errors against the truth at
    the held-out poses; and the covariance's predicted RMS against the parameters' true RMS."""
    import tempfile

    from robocal.workflows.demo.identify import simulate_and_identify

    for robot in ("so101", "koch"):
        means, maxima, ratio, nominal = [], [], [], []
        for seed in range(seeds):
            with tempfile.TemporaryDirectory() as folder:
                sim, res, held = simulate_and_identify(robot, folder, seed=seed)
            m = res.fit.problem.model
            q_new = sim.arm.sample_q(500, np.random.default_rng(1))  # the demo's 500 new poses
            nominal.append(np.linalg.norm(m.points(sim.arm.read(q_new)) - sim.arm.true_points(q_new), axis=1).mean())
            e = held * 1e3
            means.append(e.mean())
            maxima.append(e.max())
            q = sim.arm.read(sim.arm.sample_q(2000, np.random.default_rng(7)))
            true_rms = np.sqrt(np.mean(np.sum((m.points(q, res.fit.x) - m.points(q, sim.arm.x_true)) ** 2, axis=1)))
            ratio.append(res.report["errors_mm"]["predicted_rms"] / (true_rms * 1e3))
        print(
            f"{robot}, 50 planned poses per draw, 17 held-out poses vs truth, seeds 0-{seeds - 1}: mean "
            f"{min(means):.3f}-{max(means):.3f} (avg {np.mean(means):.3f}), max {min(maxima):.3f}-{max(maxima):.3f} "
            f"(avg {np.mean(maxima):.3f}) mm; draws over 0.4 mm mean: {sum(v > 0.4 for v in means)}, over 0.9 mm "
            f"max: {sum(v > 0.9 for v in maxima)}; predicted / true RMS {min(ratio):.2f}-{max(ratio):.2f}; "
            f"nominal at 500 new poses: mean {min(nominal) * 1e3:.1f}-{max(nominal) * 1e3:.1f} mm "
            f"(avg {np.mean(nominal) * 1e3:.1f}; seed 0: {nominal[0] * 1e3:.1f})"
        )


if __name__ == "__main__":
    main()
