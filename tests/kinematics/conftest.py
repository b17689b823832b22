"""Shared set-up: the shipped SO-101 URDF as a chain with a marker 20 mm off the wrist-roll axis; the
Jacobian check by central differences; ``kinematics simulate`` (a 60-pose session, any other options); tag
detection done once per rendered image (``detect_each_image_once``)."""

from __future__ import annotations

import hashlib
from collections.abc import Iterator
from importlib import resources
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from robocal.cli.main import main
from robocal.core.kinematic_errors import ErrorModel
from robocal.formats.urdf import read_urdf
from robocal.formats.urdf_chain import chain_from_urdf

SO101_URDF = resources.files("robocal") / "data" / "so101_new_calib.urdf"
KOCH_URDF = resources.files("robocal") / "data" / "koch.urdf"
# gripper_frame_joint's origin in gripper_link is (-0.0079, -0.000218, -0.0981): 7.9 mm off the roll axis (z)
MARKER_OFF_AXIS_M = (-0.0079 + 0.020, 0.0, -0.0981)
MARKER_ON_AXIS_M = (0.0, 0.0, -0.0981)
JOINTS = ("shoulder_pan", "shoulder_lift", "elbow_flex", "wrist_flex", "wrist_roll")
"""The SO-101's arm joints (the chain to gripper_link: no gripper)."""


def simulate(out: Path, *options: str) -> int:
    """``robocal kinematics simulate ... --out OUT``: its exit code."""
    return main(["kinematics", "simulate", *options, "--out", str(out)])


def identify_cli(folder: Path, data: Path, out: Path, *extra: str) -> int:
    """``robocal kinematics identify`` of ``folder/so101.urdf`` (marker off the wrist-roll axis) with ``data``,
    writing ``out/id.urdf`` and ``out/report.json``: its exit code."""
    tool = ",".join(f"{v:g}" for v in MARKER_OFF_AXIS_M)
    return main(
        [
            "kinematics", "identify", "--urdf", str(folder / "so101.urdf"), "--data", str(data),
            "--tip-link", "gripper_link", "--tool-xyz", tool, "--out", str(out / "id.urdf"),
            "--report", str(out / "report.json"), *extra,
        ]
    )  # fmt: skip


@pytest.fixture(scope="module")
def points_session(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A simulated SO-101 points session: 60 poses, seed 3 (one per test module)."""
    folder = tmp_path_factory.mktemp("sim")
    assert simulate(folder, "--poses", "60", "--seed", "3") == 0
    return folder


def so101_model(marker: tuple[float, float, float] = MARKER_OFF_AXIS_M) -> ErrorModel:
    chain = chain_from_urdf(read_urdf(str(SO101_URDF)), tip_link="gripper_link")
    T = np.eye(4)
    T[:3, 3] = marker
    return ErrorModel(chain, T_tip_tool=T)


@pytest.fixture(scope="module")
def so101() -> ErrorModel:
    return so101_model()


def truth_errors(
    true_model: ErrorModel,
    hidden: dict[str, float],
    found_urdf: Path,
    T_world_base: np.ndarray,
    T_tip_tool: np.ndarray,
) -> tuple[np.ndarray, np.ndarray]:
    """Point errors on 400 new poses of the arm with ``hidden`` errors: the identified URDF's, the nominal's (m).

    Args:
        true_model: The nominal chain with the true base and tool transforms.
        hidden: The simulator's hidden parameter values by name (truth.json).
        found_urdf: The identified URDF (its chain to the same tip link as ``true_model``).
        T_world_base: The identified base transform (the report's).
        T_tip_tool: The identified tool transform (the report's).
    """
    from robocal.backends.sim.kinematic_arm import SimulatedKinematicArm
    from robocal.core.chain import fk_chain

    arm = SimulatedKinematicArm(true_model, np.array([hidden[n] for n in true_model.names]))
    q = arm.sample_q(400, np.random.default_rng(7))
    found = chain_from_urdf(read_urdf(found_urdf), tip_link=true_model.chain.tip_link)
    T = T_world_base @ fk_chain(found, arm.read(q)) @ T_tip_tool
    err = np.linalg.norm(T[:, :3, 3] - arm.true_points(q), axis=1)
    nominal = np.linalg.norm(true_model.points(arm.read(q)) - arm.true_points(q), axis=1)
    return err, nominal


def check_jacobian(problem: Any, theta: np.ndarray, step: float | np.ndarray, rtol: float) -> np.ndarray:
    """Assert ``problem.residuals_and_jacobian(theta)`` against ``residuals`` and central differences.

    Args:
        problem: Has ``residuals(theta)`` and ``residuals_and_jacobian(theta)``.
        theta: Where to check.
        step: The difference step, one for all or one per unknown.
        rtol: Tolerance as a share of the largest Jacobian entry.

    Returns:
        The analytic Jacobian.
    """
    r, J = problem.residuals_and_jacobian(theta)
    np.testing.assert_allclose(r, problem.residuals(theta), atol=1e-12)
    steps = np.broadcast_to(np.asarray(step, dtype=float), theta.shape)
    Jn = np.zeros_like(J)
    for i in range(theta.size):
        d = np.zeros(theta.size)
        d[i] = steps[i]
        Jn[:, i] = (problem.residuals(theta + d) - problem.residuals(theta - d)) / (2 * d[i])
    np.testing.assert_allclose(J, Jn, atol=rtol * np.abs(J).max())
    return J


_DETECTIONS: dict[tuple[str, tuple[int, ...], bytes], Any] = {}
"""``robocal.backends.vision.detect``'s answers in this test session, by target and image content."""


@pytest.fixture
def detect_each_image_once(monkeypatch: pytest.MonkeyPatch) -> Iterator[None]:
    """``kinematics identify --kind tag`` detects each rendered image once per test session.

    Detecting an AprilTag with the AprilTag corner refinement takes ~0.9 s of CPU per 1280x960 image, ~95 % of an
    identification; a module's tests identify the same rendered session several times with other options. The
    first identification of an image detects it (``robocal.backends.vision.detect``, unchanged); a later one of
    the same pixels and target gets that same answer. A different image (a blank one, another session) is
    detected.
    """
    from robocal.workflows.kinematics import vision

    detect = vision.detect

    def remembered(image: Any, target: Any) -> Any:
        img = np.ascontiguousarray(image)
        key = (target.text, img.shape, hashlib.blake2b(img.tobytes(), digest_size=16).digest())
        if key not in _DETECTIONS:
            _DETECTIONS[key] = detect(img, target)
        return _DETECTIONS[key]

    monkeypatch.setattr(vision, "detect", remembered)
    yield
