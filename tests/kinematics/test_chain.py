"""core.chain and formats.urdf_chain: the one URDF-chain FK, checked against pytransform3d's URDF reader."""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import pytest
from pytransform3d.urdf import UrdfTransformManager

from robocal.core.chain import ChainJoint, SerialChain, fk_chain, rotation_about_axis
from robocal.core.se3 import rot_x, rot_y, rot_z
from robocal.errors import (
    InvalidCalibrationError,
    JointMismatchError,
    JointOutOfRangeError,
    ShapeMismatchError,
    UsageError,
)
from robocal.formats.urdf import parse_urdf, read_urdf
from robocal.formats.urdf_chain import chain_from_urdf

from .conftest import KOCH_URDF, SO101_URDF

SO101_JOINTS = ("shoulder_pan", "shoulder_lift", "elbow_flex", "wrist_flex", "wrist_roll")


def test_so101_chain_order_and_limits() -> None:
    chain = chain_from_urdf(read_urdf(str(SO101_URDF)), tip_link="gripper_frame_link")
    assert chain.joint_names == SO101_JOINTS
    assert [j.type for j in chain.joints][-1] == "fixed"
    lo, up = chain.limits()
    assert lo[0] == pytest.approx(-1.91986) and up[4] == pytest.approx(2.84121)


def test_fk_matches_pytransform3d_on_so101() -> None:
    text = SO101_URDF.read_text()
    chain = chain_from_urdf(parse_urdf(text), tip_link="gripper_frame_link")
    tm = UrdfTransformManager()
    tm.load_urdf(text)
    rng = np.random.default_rng(1)
    lo, up = chain.limits()
    q = rng.uniform(lo, up, (5, 5))
    T = fk_chain(chain, q)
    for i in range(5):
        for name, v in zip(SO101_JOINTS, q[i], strict=True):
            tm.set_joint(name, v)
        np.testing.assert_allclose(T[i], tm.get_transform("gripper_frame_link", "base_link"), atol=1e-12)
    # a pinned value: all joints at 0.1 .. 0.5 rad
    T1 = fk_chain(chain, [0.1, 0.2, 0.3, 0.4, 0.5])
    np.testing.assert_allclose(T1[:3, 3], [0.33155022, -0.03320614, 0.03216587], atol=1e-8)


def test_koch_continuous_and_axes() -> None:
    chain = chain_from_urdf(read_urdf(str(KOCH_URDF)), tip_link="gripper_tip")
    assert chain.joint_names == ("joint1", "joint2", "joint3", "joint4", "joint5")
    T = fk_chain(chain, np.zeros(5))
    # straight up: 0.039 + 0.0173 + 0.108347 + 0.002747 - 0.045 - 0.06 in z
    assert T[2, 3] == pytest.approx(0.039 + 0.0173 + 0.108347 + 0.002747 - 0.045 - 0.06)


URDF_CONT = """<robot name="r">
  <link name="a"/><link name="b"/><link name="c"/><link name="d"/>
  <joint name="j1" type="continuous"><parent link="a"/><child link="b"/><axis xyz="0 0 2"/></joint>
  <joint name="j2" type="prismatic"><origin xyz="0 0 0.1"/><parent link="b"/><child link="c"/>
    <axis xyz="1 0 0"/><limit lower="0" upper="0.2"/></joint>
  <joint name="j3" type="revolute"><parent link="b"/><child link="d"/><mimic joint="j1"/>
    <limit lower="-1" upper="1"/></joint>
</robot>"""


def test_continuous_prismatic_and_branch_errors() -> None:
    model = parse_urdf(URDF_CONT)
    with pytest.raises(JointMismatchError, match="several tip links"):
        chain_from_urdf(model)
    chain = chain_from_urdf(model, tip_link="c")
    assert chain.joints[0].type == "revolute" and chain.joints[0].lower is None
    assert chain.joints[0].axis == (0.0, 0.0, 1.0)  # normalised
    T = fk_chain(chain, [math.pi / 2, 0.15])
    np.testing.assert_allclose(T[:3, 3], [0.0, 0.15, 0.1], atol=1e-12)
    with pytest.raises(JointMismatchError, match="mimics"):
        chain_from_urdf(model, tip_link="d")
    with pytest.raises(JointMismatchError, match="no tip link 'nope'"):
        chain_from_urdf(model, tip_link="nope")
    with pytest.raises(JointMismatchError, match="not below"):
        chain_from_urdf(model, base_link="c", tip_link="d")


def test_check_q_names_row_and_joint() -> None:
    chain = chain_from_urdf(read_urdf(str(SO101_URDF)), tip_link="gripper_link")
    good = np.zeros((3, 5))
    assert chain.check_q(good).shape == (3, 5)
    bad = good.copy()
    bad[1, 2] = np.nan
    with pytest.raises(InvalidCalibrationError, match="pose 2: joint elbow_flex is nan"):
        chain.check_q(bad)
    bad[1, 2] = 2.0
    with pytest.raises(
        JointOutOfRangeError, match=r"pose 2: joint elbow_flex = 2 is outside its limits \[-1.69, 1.69\]"
    ):
        chain.check_q(bad)
    with pytest.raises(ShapeMismatchError):
        chain.check_q(np.zeros((3, 4)))


def test_chain_must_connect() -> None:
    a = ChainJoint("j1", "revolute", "base", "l1")
    b = ChainJoint("j2", "revolute", "lX", "l2")
    with pytest.raises(Exception, match="expected 'l1'"):
        SerialChain((a, b), "base", "l2")
    with pytest.raises(InvalidCalibrationError, match="zero vector"):
        SerialChain((ChainJoint("j", "revolute", "a", "b", axis=(0.0, 0.0, 0.0)),), "a", "b")


def test_one_joint_class_for_the_urdf_and_the_chain() -> None:
    # a URDF joint as parsed: URDF's default axis (1, 0, 0), its type as written; a chain takes it only as
    # revolute, prismatic or fixed (chain_from_urdf turns continuous into an unlimited revolute joint)
    j = ChainJoint("j", "continuous", "a", "b", axis=(0.0, 0.0, 2.0))
    assert j.axis == (0.0, 0.0, 1.0) and ChainJoint("k", "revolute", "a", "b").axis == (1.0, 0.0, 0.0)
    with pytest.raises(UsageError, match="type 'continuous'; a chain takes revolute, prismatic, fixed"):
        SerialChain((j,), "a", "b")
    with pytest.raises(UsageError, match="type 'ball'; a URDF joint is revolute, continuous"):
        ChainJoint("j", "ball", "a", "b")
    urdf = parse_urdf(
        b'<robot name="r"><link name="a"/><link name="b"/><joint name="j" type="continuous">'
        b'<parent link="a"/><child link="b"/><limit effort="3" velocity="2"/></joint></robot>'
    )
    parsed = urdf.joint("j")
    assert (parsed.axis, parsed.lower, parsed.effort, parsed.velocity) == ((1.0, 0.0, 0.0), None, 3.0, 2.0)
    chained = chain_from_urdf(urdf).joints[0]
    assert (chained.type, chained.axis, chained.lower, chained.upper) == ("revolute", (1.0, 0.0, 0.0), None, None)


@pytest.mark.parametrize(
    ("axis", "rot", "sign"),
    [((1, 0, 0), rot_x, 1), ((0, 1, 0), rot_y, 1), ((0, 0, 1), rot_z, 1), ((0, 0, -1), rot_z, -1)],
)
def test_rotation_about_a_coordinate_axis_is_exactly_the_coordinate_rotation(
    axis: tuple[int, int, int], rot: Any, sign: int
) -> None:
    q = np.linspace(-7.0, 7.0, 101)
    assert np.array_equal(rotation_about_axis(axis, q), rot(sign * q))  # bit for bit (no 1 - (1 - cos))
    tilted = np.array([0.0, 0.6, 0.8])
    R = rotation_about_axis(tilted, q)
    np.testing.assert_allclose(R @ tilted, np.broadcast_to(tilted, (101, 3)), atol=1e-15)  # Rodrigues
    assert np.array_equal(rotation_about_axis(tilted, 0.0), np.eye(3))
