"""Rendered tag images of a simulated Koch v1.1 (fixed camera, tag on the gripper): identified below a millimetre."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from robocal.cli.main import main

from .conftest import simulate, truth_errors

pytest.importorskip("cv2")


def test_a_koch_session_names_the_gripper_link_as_its_tip(tmp_path: Path, capsys) -> None:
    """The quick check of this module: a Koch session (points, no images) and the tip link the test below uses."""
    assert simulate(tmp_path, "--robot", "koch", "--poses", "24") == 0
    assert "--tip-link gripper_static_1" in capsys.readouterr().out
    assert json.loads((tmp_path / "truth.json").read_text())["robot"] == "koch"


@pytest.mark.slow
@pytest.mark.timeout(900)
def test_koch_tag_images_identify_the_arm(tmp_path: Path, capsys) -> None:
    from robocal.backends.vision import CameraIntrinsics
    from robocal.core.kinematic_errors import ErrorModel
    from robocal.formats.camera_info import write_camera_info
    from robocal.formats.urdf import read_urdf
    from robocal.formats.urdf_chain import chain_from_urdf
    from robocal.workflows.kinematics.vision import SIM_CAMERA_K

    code = simulate(tmp_path, "--robot", "koch", "--kind", "tag", "--poses", "24")
    assert code == 0
    assert "--tip-link gripper_static_1" in capsys.readouterr().out
    write_camera_info(tmp_path / "camera.yaml", CameraIntrinsics(1280, 960, SIM_CAMERA_K, np.zeros(5)))
    code = main(
        ["kinematics", "identify", "--kind", "tag", "--urdf", str(tmp_path / "koch.urdf"), "--data",
         str(tmp_path / "tag.csv"), "--camera", str(tmp_path / "camera.yaml"), "--target", "apriltag:36h11:0:60",
         "--tip-link", "gripper_static_1", "--out", str(tmp_path / "id.urdf"), "--report", str(tmp_path / "r.json")]
    )  # fmt: skip
    assert code in (0, 1)
    rep = json.loads((tmp_path / "r.json").read_text())
    assert rep["rank"] == 26 and rep["images"]["with_target"] == 24
    truth = json.loads((tmp_path / "truth.json").read_text())
    assert truth["robot"] == "koch"
    chain = chain_from_urdf(read_urdf(tmp_path / "koch.urdf"), tip_link="gripper_static_1")
    true_model = ErrorModel(
        chain, T_world_base=np.array(truth["T_cam_base"]), T_tip_tool=np.array(truth["T_tip_target_nominal"])
    )
    err, nominal = truth_errors(
        true_model,
        truth["hidden_parameters"],
        tmp_path / "id.urdf",
        np.array(rep["T_cam_base"]),
        np.array(rep["T_tip_target"]),
    )
    assert err.mean() <= 1e-3 and nominal.mean() > 4e-3
