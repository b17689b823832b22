"""workflows/ur/verify.py: the URDF-chain FK of an expanded UR URDF (to tool0 through the fixed frames), refusals."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from robocal.cli.main import main
from robocal.core.dh import DHParameters
from robocal.core.ur import correct_kinematics, default_kinematics
from robocal.errors import JointMismatchError
from robocal.workflows.ur.verify import urdf_fk

from .test_ur_urdf import pytransform3d_fk, ur_urdf_text


def _urdf_with(kin_text: str, old: str, new: str) -> str:
    assert old in kin_text
    return kin_text.replace(old, new)


@pytest.mark.slow
def test_urdf_fk_runs_to_tool0_through_fixed_frames(tmp_path: Path, dh_sets: dict[int, DHParameters]) -> None:
    kin = correct_kinematics(dh_sets[3])
    good = tmp_path / "good.urdf"
    good.write_text(ur_urdf_text(kin))
    q = np.random.default_rng(8).uniform(-2 * math.pi, 2 * math.pi, (20, 6))
    # an independent reader (pytransform3d, base_link_inertia → tool0) agrees with urdf_fk
    np.testing.assert_allclose(urdf_fk(good, q), pytransform3d_fk(kin, q), rtol=0, atol=1e-12)
    # a tool0 that is not the flange is caught
    bad = tmp_path / "bad.urdf"
    bad.write_text(
        _urdf_with(
            ur_urdf_text(kin), 'rpy="1.5707963267948966 0 1.5707963267948966"', 'rpy="1.5707963267948966 0 0"'
        )
    )
    dh_file = tmp_path / "dh.yaml"
    dh = dh_sets[3]
    dh_file.write_text(
        f"dh_theta: {list(dh.theta_rad)}\ndh_a: {list(dh.a_m)}\n"
        f"dh_d: {list(dh.d_m)}\ndh_alpha: {list(dh.alpha_rad)}\n"
    )
    assert main(["ur", "verify", "--dh", str(dh_file), "--urdf", str(good), "--samples", "50"]) == 0
    assert main(["ur", "verify", "--dh", str(dh_file), "--urdf", str(bad), "--samples", "50"]) == 1


@pytest.mark.parametrize(
    ("old", "new", "message"),
    [
        (
            '<joint name="wrist_1_joint" type="revolute"><parent link="forearm_link"/>',
            '<joint name="wrist_1_joint" type="revolute"><parent link="upper_arm_link"/>',
            r"wrist_1_joint's parent is upper_arm_link; expected forearm_link",
        ),
        (
            '<joint name="flange-tool0" type="fixed">',
            '<joint name="flange-tool0" '
            'type="revolute"><axis xyz="0 0 1"/><limit lower="-1" upper="1" effort="1" velocity="1"/>',
            r"flange-tool0 .* is revolute; expected fixed",
        ),
    ],
    ids=["broken-chain", "moving-joint-after-wrist_3"],
)
def test_urdf_fk_refuses_a_chain_that_is_not_ur_descriptions(
    tmp_path: Path, old: str, new: str, message: str
) -> None:
    p = tmp_path / "ur.urdf"
    p.write_text(_urdf_with(ur_urdf_text(default_kinematics("ur5e", "urdf")), old, new))
    with pytest.raises(JointMismatchError, match=message):
        urdf_fk(p, np.zeros((1, 6)))
