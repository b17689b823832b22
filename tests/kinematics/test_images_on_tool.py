"""A camera on the tool looking at a fixed target (eye-in-hand): residuals, Jacobian, hand-eye, rendered session."""

from __future__ import annotations

import math

import numpy as np

from robocal.core.kinematic_errors import ErrorModel
from robocal.core.kinematic_images import ImageObservations, ImageProblem, hand_eye
from robocal.core.se3 import homogeneous, matrix_from_rotvec

from .conftest import check_jacobian, simulate, so101_model, truth_errors

T_TARGET_BASE = homogeneous(matrix_from_rotvec([0.0, math.pi / 2, 0.0]), [0.15, 0.0, 0.4])
T_TIP_CAM = homogeneous(matrix_from_rotvec([math.pi - 0.5, 0.0, 0.0]), [0.0, 0.0, -0.03])
CORNERS = np.array([[-0.03, 0.03, 0.0], [0.03, 0.03, 0.0], [0.03, -0.03, 0.0], [-0.03, -0.03, 0.0]])


def _model() -> ErrorModel:
    return ErrorModel(so101_model((0.0, 0.0, 0.0)).chain, T_world_base=T_TARGET_BASE, T_tip_tool=T_TIP_CAM)


def test_residuals_see_the_fixed_target_through_the_inverse_tool_pose() -> None:
    model = _model()
    rng = np.random.default_rng(5)
    q = rng.uniform(-0.8, 0.8, (3, 5))
    x = rng.normal(0, 0.01, model.n_params)
    T_target_cam = model.tool_poses(q, x)
    p_cam = np.einsum("nij,kj->nki", np.linalg.inv(T_target_cam)[:, :3, :3], CORNERS)
    p_cam += np.linalg.inv(T_target_cam)[:, None, :3, 3]
    uv = (p_cam[..., :2] / p_cam[..., 2:]).reshape(-1, 2)
    obs = ImageObservations(q, np.repeat(np.arange(3), 4), np.tile(CORNERS, (3, 1)), uv, 900.0)
    on_tool = ImageProblem(
        model, obs, tuple(range(model.n_params)), np.zeros(model.n_params), camera_on_tool=True
    )
    np.testing.assert_allclose(on_tool.residuals(x), 0.0, atol=1e-7)  # pixels
    # the fixed-camera reading of the same numbers is a different set-up: it does not fit
    fixed = ImageProblem(model, obs, tuple(range(model.n_params)), np.zeros(model.n_params))
    assert np.abs(fixed.residuals(x)).max() > 10.0


def test_jacobian_matches_central_differences() -> None:
    model = _model()
    rng = np.random.default_rng(3)
    q = rng.uniform(-0.8, 0.8, (3, 5))
    obs = ImageObservations(
        q, np.repeat(np.arange(3), 4), np.tile(CORNERS, (3, 1)), rng.normal(0, 0.1, (12, 2)), 900.0
    )
    problem = ImageProblem(
        model, obs, tuple(range(model.n_params)), np.zeros(model.n_params), camera_on_tool=True
    )
    theta = rng.normal(0, 0.01, model.n_params)
    J = check_jacobian(problem, theta, 1e-7, 1e-5)
    assert np.abs(J[:, model.index("tool.rx")]).max() > 100.0  # the camera's tilt on the tool moves the image


def test_hand_eye_on_the_tool_from_inverted_pnp_poses() -> None:
    model = _model()
    q = np.random.default_rng(4).uniform(-1, 1, (8, 5))
    F = ErrorModel(model.chain).tool_poses(q)  # T_base_tip
    T_cam_target = np.linalg.inv(T_TARGET_BASE @ F @ T_TIP_CAM)
    X, Y = hand_eye(np.linalg.inv(T_cam_target), F)
    np.testing.assert_allclose(X, T_TARGET_BASE, atol=1e-9)
    np.testing.assert_allclose(Y, T_TIP_CAM, atol=1e-9)


# --- a rendered eye-in-hand session through the CLI (needs OpenCV) ------------------------------------------------

import json  # noqa: E402
from pathlib import Path  # noqa: E402

import pytest  # noqa: E402

from robocal.cli.main import main  # noqa: E402


@pytest.fixture(scope="module")
def session(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """30 rendered images from a camera on the gripper of a simulated SO-101 with hidden errors, looking at a
    tag standing in front of the arm; the camera's true intrinsics (camera-calibrate is tested elsewhere)."""
    pytest.importorskip("cv2")
    from robocal.backends.vision import CameraIntrinsics
    from robocal.formats.camera_info import write_camera_info
    from robocal.workflows.kinematics.vision import SIM_CAMERA_K, SimImagesRequest, simulate_images

    folder = tmp_path_factory.mktemp("eye_in_hand")
    simulate_images(
        SimImagesRequest("so101", folder, poses=30, seed=2, camera_on_tool=True, calibration_images=0)
    )
    write_camera_info(folder / "camera.yaml", CameraIntrinsics(1280, 960, SIM_CAMERA_K, np.zeros(5)))
    return folder


def _identify(session: Path, tmp: Path, *extra: str) -> int:
    return main(
        ["kinematics", "identify", "--kind", "tag", "--urdf", str(session / "so101.urdf"), "--data",
         str(session / "tag.csv"), "--camera", str(session / "camera.yaml"), "--target", "apriltag:36h11:0:60",
         "--tip-link", "gripper_link", "--out", str(tmp / "id.urdf"), "--report", str(tmp / "r.json"), *extra]
    )  # fmt: skip


@pytest.mark.slow
@pytest.mark.timeout(900)
@pytest.mark.usefixtures("detect_each_image_once")  # the two tests identify the same session
def test_camera_on_the_tool_identifies_the_arm_below_a_millimetre(
    session: Path, tmp_path: Path, capsys
) -> None:
    from robocal.formats.urdf import read_urdf
    from robocal.formats.urdf_chain import chain_from_urdf

    code = _identify(session, tmp_path, "--camera-on-tool")
    out = capsys.readouterr().out
    assert code in (0, 1)
    assert (
        "30 of 30 images show the target; rank 26 of 47 unknowns (base.* = target place, tool.* = camera"
        in out
    )
    rep = json.loads((tmp_path / "r.json").read_text())
    assert rep["setup"] == "camera on the tool, target fixed in the world"
    assert "T_cam_base" not in rep and rep["images"]["fit"] == 22
    assert rep["reprojection_px"]["validation"]["start"]["mean"] > 5.0
    assert rep["reprojection_px"]["validation"]["identified"]["mean"] < 2.5
    # against the hidden truth, in the target's frame (the one the images see): the camera on new poses
    truth = json.loads((session / "truth.json").read_text())
    chain = chain_from_urdf(read_urdf(session / "so101.urdf"), tip_link="gripper_link")
    true_model = ErrorModel(
        chain,
        T_world_base=np.array(truth["T_target_base"]),
        T_tip_tool=np.array(truth["T_tip_camera_nominal"]),
    )
    err, nominal = truth_errors(
        true_model,
        truth["hidden_parameters"],
        tmp_path / "id.urdf",
        np.array(rep["T_target_base"]),
        np.array(rep["T_tip_camera"]),
    )
    assert err.mean() <= 1e-3 and nominal.mean() > 4e-3
    # the camera's mounting on the tool is found within a few millimetres of the true one
    mount = np.array(rep["T_tip_camera"])[:3, 3]
    assert np.linalg.norm(mount - np.array(truth["T_tip_camera_nominal"])[:3, 3]) < 5e-3


@pytest.mark.slow
@pytest.mark.timeout(900)
@pytest.mark.usefixtures("detect_each_image_once")  # the two tests identify the same session
def test_refine_intrinsics_from_the_cli_reports_the_camera_matrix(
    session: Path, tmp_path: Path, capsys
) -> None:
    from robocal.workflows.kinematics.vision import SIM_CAMERA_K

    assert _identify(session, tmp_path, "--camera-on-tool", "--refine-intrinsics") in (0, 1)
    out = capsys.readouterr().out
    assert "rank 30 of 51 unknowns" in out  # 26 + fx, fy, cx, cy
    rep = json.loads((tmp_path / "r.json").read_text())
    intr = rep["intrinsics"]
    assert intr["refined"] is True and intr["K_calibrated"] == SIM_CAMERA_K.tolist()
    K = np.array(intr["K"])
    assert np.abs(K[[0, 1, 0, 1], [0, 1, 2, 2]] - SIM_CAMERA_K[[0, 1, 0, 1], [0, 1, 2, 2]]).max() < 15.0
    assert all(0.0 < v < 10.0 for v in intr["sigma_px"].values())
    assert [p["name"] for p in rep["parameters"][-4:]] == ["camera.fx", "camera.fy", "camera.cx", "camera.cy"]
    assert {p["unit"] for p in rep["parameters"][-4:]} == {"px"}
    assert rep["reprojection_px"]["validation"]["identified"]["mean"] < 2.5


def test_camera_on_tool_needs_tag_images(tmp_path: Path, capsys) -> None:
    code = simulate(tmp_path, "--camera-on-tool")
    assert code == 2
    assert capsys.readouterr().err.strip() == "error: --camera-on-tool applies to --kind tag (camera images)"
    assert list(tmp_path.iterdir()) == []


def test_camera_on_tool_is_simulated_for_the_so101_only(tmp_path: Path, capsys) -> None:
    code = simulate(tmp_path, "--robot", "koch", "--kind", "tag", "--camera-on-tool")
    assert code == 2
    err = capsys.readouterr().err.strip()
    assert err == "error: tag images with the camera on the tool are simulated for so101 only, not 'koch'"
    assert list(tmp_path.iterdir()) == []
