"""Shared set-up: the shipped SO-101 URDF as a chain with a marker 20 mm off the wrist-roll axis."""

from __future__ import annotations

from importlib import resources

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
