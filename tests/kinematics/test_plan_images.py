"""Camera (tag) pose planning: ``kinematics plan --kind tag`` and :func:`robocal.core.pose_plan.plan_image_poses`."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from robocal.cli.main import main
from robocal.core.kinematic_errors import ErrorModel
from robocal.core.pose_plan import image_plan_problem, plan_image_poses, target_visible
from robocal.core.se3 import homogeneous, matrix_from_rpy_urdf
from robocal.errors import UsageError
from robocal.formats.kinematic_data import read_pose_plan
from robocal.formats.urdf import read_urdf
from robocal.formats.urdf_chain import chain_from_urdf
from robocal.workflows.kinematics.sim import shipped_urdf
from robocal.workflows.kinematics.vision_sim import SIM_CAMERA_K, look_at

TAG = np.array([[-0.03, 0.03, 0.0], [0.03, 0.03, 0.0], [0.03, -0.03, 0.0], [-0.03, -0.03, 0.0]])  # 60 mm
SIZE = (1280, 960)
EYE, CENTRE = (-0.08, 0.0, 0.55), (0.11, 0.0, 0.19)
MOUNT = (0.0121, 0.0, -0.0981)


def _chain():
    return chain_from_urdf(read_urdf(shipped_urdf("so101")), tip_link="gripper_link")


def _fixed_model() -> ErrorModel:
    return ErrorModel(
        _chain(), T_world_base=np.linalg.inv(look_at(EYE, CENTRE)), T_tip_tool=homogeneous(np.eye(3), MOUNT)
    )


def _on_tool_model() -> ErrorModel:
    T_base_target = homogeneous(matrix_from_rpy_urdf(np.array([0.0, -math.pi / 2, 0.0])), [0.4, 0.0, 0.15])
    mount = homogeneous(matrix_from_rpy_urdf(np.array([math.pi - 0.5, 0.0, 0.0])), [0.0, 0.0, -0.03])
    return ErrorModel(_chain(), T_world_base=np.linalg.inv(T_base_target), T_tip_tool=mount)


def _visible_candidates(model: ErrorModel, on_tool: bool, n: int, seed: int) -> np.ndarray:
    lo, up = model.chain.limits()
    q = np.random.default_rng(seed).uniform(lo + 0.05, up - 0.05, (n, model.chain.n_q))
    T = model.tool_poses(q)
    return q[target_visible(np.linalg.inv(T) if on_tool else T, TAG, (0, 0, 1), SIM_CAMERA_K, SIZE)]


def _predicted_sigma(model: ErrorModel, q_images: np.ndarray, q_all: np.ndarray, on_tool: bool) -> float:
    """The measured point's σ over ``q_all`` after a fit from images at ``q_images`` (0.3 px), linearised."""
    everything = image_plan_problem(model, q_all, TAG, SIM_CAMERA_K, camera_on_tool=on_tool)
    cols = list(everything.analyse().base)
    problem = image_plan_problem(model, q_images, TAG, SIM_CAMERA_K, camera_on_tool=on_tool)
    _, J = problem.residuals_and_jacobian(problem.initial_theta())
    cov = np.linalg.inv(J[:, cols].T @ J[:, cols] / 0.3**2)
    _, G = model.point_jacobian(q_all)
    G = G[:, :, cols]
    return float(np.sqrt(np.mean(np.einsum("nrk,kl,nrl->n", G, cov, G))))


@pytest.mark.slow
@pytest.mark.parametrize("on_tool", [False, True], ids=["camera-fixed", "camera-on-tool"])
def test_planned_images_predict_better_than_random_visible_ones(on_tool: bool) -> None:
    model = _on_tool_model() if on_tool else _fixed_model()
    cand = _visible_candidates(model, on_tool, 60_000 if on_tool else 3000, seed=1)
    assert cand.shape[0] >= 150
    cand = cand[:600]
    plan = plan_image_poses(model, cand, TAG, SIM_CAMERA_K, 25, camera_on_tool=on_tool)
    assert plan.index.shape == (25,) and len(set(plan.index.tolist())) == 25
    assert plan.identifiability.rank == plan.candidates.rank == 26
    planned = _predicted_sigma(model, cand[plan.index], cand, on_tool)
    assert plan.prediction_sigma_m == pytest.approx(planned, rel=1e-6)
    rng = np.random.default_rng(3)
    random = [
        _predicted_sigma(model, cand[rng.permutation(cand.shape[0])[:25]], cand, on_tool) for _ in range(5)
    ]
    assert planned < 0.85 * min(random), (planned, random)


@pytest.mark.slow
def test_refining_the_intrinsics_adds_four_unknowns_to_the_plan() -> None:
    model = _fixed_model()
    cand = _visible_candidates(model, False, 3000, seed=2)[:300]
    plan = plan_image_poses(model, cand, TAG, SIM_CAMERA_K, 20, refine_intrinsics=True)
    assert plan.identifiability.rank == 30
    assert plan.identifiability.names[-4:] == ("camera.fx", "camera.fy", "camera.cx", "camera.cy")


@pytest.mark.slow
def test_too_few_images_or_candidates_are_refused() -> None:
    model = _fixed_model()
    cand = _visible_candidates(model, False, 3000, seed=2)[:100]
    with pytest.raises(
        UsageError,
        match=r"too few poses: 4 images show 24 numbers \(the target's pose in each\), "
        "not more than the 26 unknowns the candidates can identify; plan at least 6 images",
    ):
        plan_image_poses(model, cand, TAG, SIM_CAMERA_K, 4)
    assert plan_image_poses(model, cand, TAG, SIM_CAMERA_K, 5).index.shape == (5,)
    with pytest.raises(UsageError, match="sees the whole target in only 100 candidate poses"):
        plan_image_poses(model, cand, TAG, SIM_CAMERA_K, 101)
    with pytest.raises(UsageError, match="--noise-px"):
        plan_image_poses(model, cand, TAG, SIM_CAMERA_K, 20, noise_px=0.0)


def test_visibility_needs_the_whole_target_facing_the_camera() -> None:
    T = np.tile(np.eye(4), (5, 1, 1))
    T[:, 2, 3] = 0.4  # 0.4 m in front, facing away from the camera (+z normal points away)
    T[1, :3, :3] = matrix_from_rpy_urdf(np.array([math.pi, 0.0, 0.0]))  # turned to face the camera
    T[2, :3, :3] = T[1, :3, :3]
    T[2, 0, 3] = 0.25  # far to the side: corners off the image
    T[3, :3, :3] = T[1, :3, :3]
    T[3, 2, 3] = 0.1  # nearer than 0.15 m
    T[4, :3, :3] = matrix_from_rpy_urdf(np.array([math.pi + 1.1, 0.0, 0.0]))  # 63° off the camera axis
    seen = target_visible(T, TAG, (0.0, 0.0, 1.0), SIM_CAMERA_K, SIZE)
    assert seen.tolist() == [False, True, False, False, False]


def _camera_yaml(tmp: Path) -> Path:
    from robocal.backends.vision import CameraIntrinsics
    from robocal.formats.camera_info import write_camera_info

    return write_camera_info(tmp / "camera.yaml", CameraIntrinsics(1280, 960, SIM_CAMERA_K, np.zeros(5)))


def _plan_args(tmp: Path, *extra: str) -> list[str]:
    return [
        "kinematics", "plan", "--kind", "tag", "--urdf", str(shipped_urdf("so101")), "--tip-link", "gripper_link",
        "--camera", str(_camera_yaml(tmp)), "--target", "apriltag:36h11:0:60", "--out", str(tmp / "plan.csv"),
        *extra,
    ]  # fmt: skip


@pytest.mark.slow
def test_cli_plans_images_the_camera_sees(tmp_path: Path, capsys) -> None:
    pytest.importorskip("cv2")  # parse_target needs cv2.aruco
    code = main(
        _plan_args(
            tmp_path, "--camera-pose=-0.08,0,0.55", "--look-at", "0.11,0,0.19", "--target-pose",
            "0.0121,0,-0.0981,0,0,0", "--poses", "24", "--candidates", "400",
        )
    )  # fmt: skip
    out = capsys.readouterr().out
    assert code == 0, out
    assert "24 images (I-optimal of 400 poses where the camera sees the target" in out
    assert "rank 26 of 47 unknowns" in out
    assert "predicted σ of the target's centre in the camera frame" in out
    model = _fixed_model()
    q, labels = read_pose_plan(tmp_path / "plan.csv", model.chain.joint_names)
    assert q.shape == (24, 5) and labels == ()
    assert target_visible(model.tool_poses(q), TAG, (0, 0, 1), SIM_CAMERA_K, SIZE).all()


@pytest.mark.slow
def test_cli_plans_a_camera_on_the_tool(tmp_path: Path, capsys) -> None:
    pytest.importorskip("cv2")
    code = main(
        _plan_args(
            tmp_path, "--camera-on-tool", "--camera-pose", f"0,0,-0.03,{math.pi - 0.5},0,0", "--target-pose",
            f"0.4,0,0.15,0,{-math.pi / 2},0", "--poses", "20", "--candidates", "200",
        )
    )  # fmt: skip
    out = capsys.readouterr().out
    assert code == 0, out
    assert "predicted σ of the camera's centre in the target frame" in out
    model = _on_tool_model()
    q, _ = read_pose_plan(tmp_path / "plan.csv", model.chain.joint_names)
    assert q.shape == (20, 5)
    assert target_visible(np.linalg.inv(model.tool_poses(q)), TAG, (0, 0, 1), SIM_CAMERA_K, SIZE).all()


@pytest.mark.slow
@pytest.mark.parametrize(
    ("extra", "message"),
    [
        ((), "--kind tag needs --camera (intrinsics), --target and --camera-pose"),
        (("--camera-pose", "0,0,0.5"), "--camera-pose: expected x,y,z,roll,pitch,yaw"),
        (("--camera-pose", "0,0,0.5,0,0,nan"), "--camera-pose '0,0,0.5,0,0,nan': expected finite numbers"),
        (("--camera-pose", "0,0,0.5", "--look-at", "0,0,0.5"), "cannot look at its own position"),
        (
            ("--camera-pose", "0,0,-0.5", "--look-at", "0,0,-1"),
            "sees the whole target apriltag:36h11:0:60 in none",
        ),
        (
            ("--camera-pose=-0.08,0,0.55", "--look-at", "0.11,0,0.19", "--poses", "3"),
            "too few poses: 3 images",
        ),
        (
            ("--camera-pose=-0.08,0,0.55", "--look-at", "0.11,0,0.19", "--tool-xyz", "0,0,0.1"),
            "not for --kind tag",
        ),
        (
            ("--camera-pose=-0.08,0,0.55", "--look-at", "0.11,0,0.19", "--criterion", "d", "--prior"),
            "--criterion d: not for --kind tag",
        ),
        (
            ("--camera-pose", "0,0,0,0,0,0", "--look-at", "1,0,0", "--camera-on-tool"),
            "--look-at places a fixed",
        ),
    ],
)
def test_cli_tag_plan_errors_write_nothing(
    tmp_path: Path, capsys, extra: tuple[str, ...], message: str
) -> None:
    pytest.importorskip("cv2")
    (tmp_path / "plan.csv").write_text("old\n")
    code = main(_plan_args(tmp_path, *extra))
    err = capsys.readouterr().err
    assert code == 2
    assert message in err and err.count("error:") == 1 and "Traceback" not in err
    assert (tmp_path / "plan.csv").read_text() == "old\n" and not (tmp_path / "plan.csv.bak").exists()


def test_tag_options_without_kind_tag_are_refused(tmp_path: Path, capsys) -> None:
    code = main(
        ["kinematics", "plan", "--urdf", str(shipped_urdf("so101")), "--tip-link", "gripper_link", "--out",
         str(tmp_path / "p.csv"), "--camera-on-tool", "--noise-px", "1"]
    )  # fmt: skip
    assert code == 2
    assert "error: --camera-on-tool, --noise-px apply to --kind tag" in capsys.readouterr().err
    assert not (tmp_path / "p.csv").exists()


def _posterior_sigma(
    model: ErrorModel, q_images: np.ndarray, q_all: np.ndarray, sig: np.ndarray, noise_px: float
) -> float:
    """The target centre's σ over ``q_all`` after a MAP fit with prior σ ``sig`` (inf: none) from the images."""
    everything = image_plan_problem(model, q_all, TAG, SIM_CAMERA_K)
    cols = sorted(set(everything.analyse().base) | set(np.flatnonzero(np.isfinite(sig)).tolist()))
    problem = image_plan_problem(model, q_images, TAG, SIM_CAMERA_K)
    _, J = problem.residuals_and_jacobian(problem.initial_theta())
    info = J[:, cols].T @ J[:, cols] / noise_px**2 + np.diag(np.where(np.isfinite(sig[cols]), sig[cols] ** -2.0, 0.0))
    _, G = model.point_jacobian(q_all)
    G = G[:, :, cols]
    return float(np.sqrt(np.mean(np.einsum("nrk,kl,nrl->n", G, np.linalg.inv(info), G))))


@pytest.mark.slow
def test_bayesian_tag_plan_counts_the_kinematic_prior_only() -> None:
    from robocal.workflows.kinematics.fit import PriorSigmas

    model = _fixed_model()
    cand = _visible_candidates(model, False, 3000, seed=4)[:300]
    sig = PriorSigmas().model_sigmas(model, tool_free=True)
    assert np.isinf(sig[model.index("base.x")]) and np.isinf(sig[model.index("tool.rz")])  # camera, mounting
    assert sig[model.index("shoulder_pan.offset")] == pytest.approx(math.radians(2.0))
    # with noisy images (2 px) the prior weighs enough to change the plan
    plain = plan_image_poses(model, cand, TAG, SIM_CAMERA_K, 12, noise_px=2.0)
    bayes = plan_image_poses(model, cand, TAG, SIM_CAMERA_K, 12, noise_px=2.0, prior_sigma=sig)
    assert sorted(bayes.index.tolist()) != sorted(plain.index.tolist())
    assert bayes.index[:5].tolist() == plain.index[:5].tolist()  # the same D-optimal start
    # the printed σ is the posterior with the prior, and the Bayesian plan is the better one for a prior fit
    with_prior = _posterior_sigma(model, cand[bayes.index], cand, sig, 2.0)
    assert bayes.prediction_sigma_m == pytest.approx(with_prior, rel=1e-6)
    assert with_prior < _posterior_sigma(model, cand[plain.index], cand, sig, 2.0)
    assert with_prior < plain.prediction_sigma_m  # the prior adds information
    assert bayes.identifiability.rank == 26  # the rank is the data's, as identify reports it
    bad = sig.copy()
    bad[3] = 0.0
    with pytest.raises(UsageError, match="prior σ must be 47 positive values"):
        plan_image_poses(model, cand, TAG, SIM_CAMERA_K, 12, prior_sigma=bad)


@pytest.mark.slow
def test_cli_plans_tag_images_with_a_prior(tmp_path: Path, capsys) -> None:
    pytest.importorskip("cv2")
    args = ("--camera-pose=-0.08,0,0.55", "--look-at", "0.11,0,0.19", "--target-pose", "0.0121,0,-0.0981,0,0,0",
            "--poses", "12", "--candidates", "300")  # fmt: skip
    assert main(_plan_args(tmp_path, *args)) == 0
    plain_out = capsys.readouterr().out
    plain, _ = read_pose_plan(tmp_path / "plan.csv", _fixed_model().chain.joint_names)
    assert main(_plan_args(tmp_path, *args, "--prior")) == 0
    out = capsys.readouterr().out
    assert "12 images (Bayesian I-optimal of 300 poses where the camera sees the target" in out
    assert "0.3 px corner noise, with the tolerance prior)" in out and "with the tolerance prior" not in plain_out
    bayes, _ = read_pose_plan(tmp_path / "plan.csv", _fixed_model().chain.joint_names)
    assert bayes.shape == (12, 5) and not np.allclose(np.sort(bayes, axis=0), np.sort(plain, axis=0))
    assert (tmp_path / "plan.csv.bak").exists()  # the first plan, kept
