"""Shared set-up: the shipped SO-101 URDF as a chain with a marker 20 mm off the wrist-roll axis; the
Jacobian check by central differences."""

from __future__ import annotations

from importlib import resources
from typing import Any

import numpy as np
import pytest

from robocal.core.kinematic_errors import ErrorModel
from robocal.formats.urdf import read_urdf
from robocal.formats.urdf_chain import chain_from_urdf

SO101_URDF = resources.files("robocal") / "data" / "so101_new_calib.urdf"
KOCH_URDF = resources.files("robocal") / "data" / "koch.urdf"
# gripper_frame_joint's origin in gripper_link is (-0.0079, -0.000218, -0.0981): 7.9 mm off the roll axis (z)
MARKER_OFF_AXIS_M = (-0.0079 + 0.020, 0.0, -0.0981)
MARKER_ON_AXIS_M = (0.0, 0.0, -0.0981)


def so101_model(marker: tuple[float, float, float] = MARKER_OFF_AXIS_M) -> ErrorModel:
    chain = chain_from_urdf(read_urdf(str(SO101_URDF)), tip_link="gripper_link")
    T = np.eye(4)
    T[:3, 3] = marker
    return ErrorModel(chain, T_tip_tool=T)


@pytest.fixture(scope="module")
def so101() -> ErrorModel:
    return so101_model()


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
