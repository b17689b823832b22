"""Camera intrinsics refined jointly with the kinematics (``--refine-intrinsics``): Jacobian, recovery, CLI."""

from __future__ import annotations

import numpy as np
import pytest

from robocal.core.kinematic_errors import ErrorModel
from robocal.core.kinematic_images import INTRINSICS, ImageObservations, ImageProblem
from robocal.core.se3 import homogeneous
from robocal.errors import InvalidCalibrationError, UsageError
from robocal.workflows.kinematics.fit import fit
from robocal.workflows.kinematics.vision_sim import SIM_CAMERA_K, look_at

from .conftest import check_jacobian, so101_model

CORNERS = np.array([[-0.03, 0.03, 0.0], [0.03, 0.03, 0.0], [0.03, -0.03, 0.0], [-0.03, -0.03, 0.0]])
T_CAM_BASE = np.linalg.inv(look_at((-0.08, 0.0, 0.55), (0.11, 0.0, 0.19)))
MOUNT = homogeneous(np.eye(3), [0.0121, 0.0, -0.0981])


def _session(K_calibrated: np.ndarray, n: int = 40, seed: int = 0, noise_px: float = 0.2):
    """Corners of a tag on the tool seen by a camera with the true intrinsics SIM_CAMERA_K; normalised with
    ``K_calibrated`` (what a wrong calibration gives). Returns the observations, the nominal model and the truth."""
    model = ErrorModel(so101_model((0.0, 0.0, 0.0)).chain, T_world_base=T_CAM_BASE, T_tip_tool=MOUNT)
    rng = np.random.default_rng(seed)
    x_true = np.zeros(model.n_params)
    for i, p in enumerate(model.parameters):
        if p.group not in ("base", "tool"):
            x_true[i] = rng.normal(
                0, np.radians(2.0) if p.kind == "offset" else (1e-3 if p.unit == "m" else 0.0087)
            )
    q_all = rng.uniform(-0.9, 0.9, (4000, 5))
    T = model.tool_poses(q_all, x_true)
    p = np.einsum("nij,kj->nki", T[:, :3, :3], CORNERS) + T[:, None, :3, 3]
    pix = np.einsum("ij,nkj->nki", SIM_CAMERA_K, p)
    pix = pix[..., :2] / pix[..., 2:]
    ok = np.all(
        (p[..., 2] > 0.15)
        & (pix[..., 0] > 20)
        & (pix[..., 0] < 1260)
        & (pix[..., 1] > 20)
        & (pix[..., 1] < 940),
        axis=1,
    )
    rows = np.flatnonzero(ok)[:n]
    pix = pix[rows] + rng.normal(0, noise_px, pix[rows].shape)
    uv = (pix - K_calibrated[:2, 2]) / K_calibrated[[0, 1], [0, 1]]
    obs = ImageObservations(
        q_all[rows], np.repeat(np.arange(rows.size), 4), np.tile(CORNERS, (rows.size, 1)), uv.reshape(-1, 2),
        float(K_calibrated[0, 0] + K_calibrated[1, 1]) / 2, K=K_calibrated,
    )  # fmt: skip
    return obs, model, x_true


def test_jacobian_with_intrinsics_matches_central_differences() -> None:
    obs, model, _ = _session(SIM_CAMERA_K, n=4)
    problem = ImageProblem(
        model, obs, tuple(range(model.n_params)), np.zeros(model.n_params), refine_intrinsics=True
    )
    assert problem.names[-4:] == INTRINSICS and problem.n_theta == model.n_params + 4
    theta = np.concatenate([np.random.default_rng(1).normal(0, 0.01, model.n_params), [3.0, -2.0, 1.5, 4.0]])
    steps = np.where(np.arange(problem.n_theta) < model.n_params, 1e-7, 1e-4)
    check_jacobian(problem, theta, steps, 1e-5)
    np.testing.assert_allclose(
        problem.camera_matrix(theta)[[0, 1, 0, 1], [0, 1, 2, 2]],
        SIM_CAMERA_K[[0, 1, 0, 1], [0, 1, 2, 2]] + [3.0, -2.0, 1.5, 4.0],
    )


@pytest.mark.slow
def test_a_wrong_calibration_is_refined_and_the_arm_is_found_better() -> None:
    K_wrong = SIM_CAMERA_K.copy()
    K_wrong[0, 0] *= 1.02  # 2 % focal length error, principal point 8 px off
    K_wrong[1, 1] *= 1.02
    K_wrong[0, 2] += 8.0
    obs, model, x_true = _session(K_wrong)
    free = tuple(range(model.n_params))
    plain = fit(ImageProblem(model, obs, free, np.zeros(model.n_params)))
    refined = fit(ImageProblem(model, obs, free, np.zeros(model.n_params), refine_intrinsics=True))
    K = refined.problem.camera_matrix(refined.theta)
    assert abs(K[0, 0] - SIM_CAMERA_K[0, 0]) < 0.3 * abs(K_wrong[0, 0] - SIM_CAMERA_K[0, 0])
    assert abs(K[0, 2] - SIM_CAMERA_K[0, 2]) < 0.5 * abs(K_wrong[0, 2] - SIM_CAMERA_K[0, 2])
    # the target in the camera frame on new poses: refining beats trusting the wrong calibration
    q = np.random.default_rng(9).uniform(-0.9, 0.9, (300, 5))
    truth = model.points(q, x_true)
    e_plain = np.linalg.norm(model.points(q, plain.x) - truth, axis=1).mean()
    e_refined = np.linalg.norm(model.points(q, refined.x) - truth, axis=1).mean()
    assert e_refined < 0.5 * e_plain
    assert np.sqrt(np.mean(refined.problem.residuals(refined.theta) ** 2)) < 0.3  # the pixel noise (0.2 px)


def test_refining_needs_the_camera_matrix() -> None:
    obs, model, _ = _session(SIM_CAMERA_K, n=4)
    bare = ImageObservations(obs.q_rad, obs.pose, obs.corner_m, obs.uv, obs.focal_px)
    with pytest.raises(UsageError, match="refining the intrinsics needs the camera matrix"):
        ImageProblem(model, bare, (0,), np.zeros(model.n_params), refine_intrinsics=True)
    with pytest.raises(InvalidCalibrationError, match="camera matrix must be a finite"):
        ImageObservations(obs.q_rad, obs.pose, obs.corner_m, obs.uv, obs.focal_px, K=np.full((3, 3), np.nan))


def test_refine_intrinsics_is_for_tag_images(tmp_path, capsys) -> None:
    from robocal.cli.main import main

    code = main(["kinematics", "identify", "--urdf", "x.urdf", "--data", "d.csv", "--refine-intrinsics"])
    assert code == 2
    assert (
        capsys.readouterr().err.strip() == "error: --refine-intrinsics applies to --kind tag (camera images)"
    )


@pytest.mark.slow
def test_prior_on_image_data_estimates_every_joint_parameter_but_not_the_camera() -> None:
    from robocal.workflows.kinematics.fit import PriorSigmas

    obs, model, x_true = _session(SIM_CAMERA_K, n=30, seed=4)
    problem = ImageProblem(model, obs, tuple(range(model.n_params)), np.zeros(model.n_params))
    plain = fit(problem)
    with_prior = fit(problem, prior=PriorSigmas())
    estimated = np.isfinite(with_prior.sigma)
    names = problem.names
    joint = [i for i, n in enumerate(names) if not n.startswith(("base.", "tool."))]
    assert estimated[joint].all()  # every joint parameter, the unidentifiable ones too
    assert not np.isfinite(plain.sigma[joint]).all()
    # the camera pose and the target mounting have no prior: only their identifiable part is estimated
    others = [i for i in range(len(names)) if i not in joint]
    assert set(np.flatnonzero(estimated[others])) == set(np.flatnonzero(np.isfinite(plain.sigma[others])))
    q = np.random.default_rng(9).uniform(-0.9, 0.9, (300, 5))
    truth = model.points(q, x_true)
    assert np.linalg.norm(model.points(q, with_prior.x) - truth, axis=1).mean() < 1e-3
