"""Gravity torque from a URDF's inertials (core.gravity, formats.urdf_gravity): hand-computed arms, the SO-101
URDF against an independent FK (pytransform3d, potential energy differentiated), bad files."""

from __future__ import annotations

import math
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from tests.robots import SO101_JOINTS

from robocal.core.chain import ChainJoint
from robocal.core.gravity import GravityModel, LinkInertial, gravity_torques, joint_gravity
from robocal.errors import FileFormatError, InvalidCalibrationError, JointMismatchError, ShapeMismatchError
from robocal.formats.urdf import UrdfDocument
from robocal.formats.urdf_gravity import gravity_model_from_urdf, gravity_model_if_any

G = 9.80665
DATA = Path(__file__).resolve().parents[2] / "src" / "robocal" / "data"

TWO_LINK = """<?xml version="1.0"?>
<robot name="two_link">
  <link name="base"/>
  <link name="l1"><inertial><origin xyz="0.2 0 0" rpy="0.3 0 0"/><mass value="1.0"/>
    <inertia ixx="1" iyy="1" izz="1" ixy="0" ixz="0" iyz="0"/></inertial></link>
  <link name="l2"><inertial><origin xyz="0.15 0 0"/><mass value="0.5"/></inertial></link>
  <joint name="j1" type="revolute"><parent link="base"/><child link="l1"/>
    <axis xyz="0 1 0"/><limit lower="-3" upper="3" effort="1" velocity="1"/></joint>
  <joint name="j2" type="continuous"><parent link="l1"/><child link="l2"/>
    <origin xyz="0.4 0 0"/><axis xyz="0 1 0"/></joint>
</robot>
"""
"""Two links in the x–z plane turning about +y: a positive angle lowers the arm (x → (cos q, 0, −sin q))."""


def two_link() -> GravityModel:
    return gravity_model_from_urdf(UrdfDocument.from_bytes(TWO_LINK))


def expected_two_link(q1: float, q2: float) -> tuple[float, float]:
    """By hand: τ = Σ m·g·(horizontal lever arm) about each joint, positive lowering the arm."""
    t2 = 0.5 * G * 0.15 * math.cos(q1 + q2)
    t1 = 1.0 * G * 0.2 * math.cos(q1) + 0.5 * G * (0.4 * math.cos(q1) + 0.15 * math.cos(q1 + q2))
    return t1, t2


def test_two_link_arm_hand_computed_values() -> None:
    m = two_link()
    assert m.joint_names == ("j1", "j2")
    assert m.total_mass_kg == pytest.approx(1.5)
    # horizontal: j1 carries 1 kg at 0.2 m and 0.5 kg at 0.55 m; j2 carries 0.5 kg at 0.15 m
    np.testing.assert_allclose(gravity_torques(m, [0.0, 0.0]), [G * 0.475, G * 0.075], atol=1e-12)
    assert gravity_torques(m, [0.0, 0.0])[0] == pytest.approx(4.65816, abs=1e-5)
    # hanging straight down: no torque; elbow bent down 90°: j1 sees 1 kg at 0.2 and 0.5 kg at 0.4
    np.testing.assert_allclose(gravity_torques(m, [math.pi / 2, 0.0]), [0.0, 0.0], atol=1e-12)
    np.testing.assert_allclose(gravity_torques(m, {"j2": math.pi / 2}), [G * 0.4, 0.0], atol=1e-12)
    # batched
    q = np.array([[0.3, -0.7], [1.2, 0.4]])
    np.testing.assert_allclose(gravity_torques(m, q), [expected_two_link(*row) for row in q], atol=1e-12)


@settings(max_examples=60, deadline=None)
@given(st.floats(-3.0, 3.0), st.floats(-3.0, 3.0))
def test_two_link_matches_the_formula_everywhere(q1: float, q2: float) -> None:
    np.testing.assert_allclose(gravity_torques(two_link(), [q1, q2]), expected_two_link(q1, q2), atol=1e-10)


def test_joint_gravity_is_a_sine_of_its_own_angle() -> None:
    m = two_link()
    jg = joint_gravity(m, "j1", {"j2": 0.5})
    # τ1(q1) = g·(0.2 + 0.2)·cos q1 + 0.5·g·0.15·cos(q1 + 0.5)
    for q1 in np.linspace(-3, 3, 13):
        assert jg(q1) == pytest.approx(expected_two_link(q1, 0.5)[0], abs=1e-12)
    assert jg.amplitude_nm == pytest.approx(
        max(abs(jg(q)) for q in np.linspace(-math.pi, math.pi, 20001)), rel=1e-6
    )
    assert jg(jg.hanging_rad) == pytest.approx(0.0, abs=1e-12)
    # hanging is the stable zero: the torque pulls back towards it from both sides
    assert jg(jg.hanging_rad + 0.1) < 0 < jg(jg.hanging_rad - 0.1)
    # the pose entry of the joint itself is ignored
    assert joint_gravity(m, "j1", {"j1": 2.0, "j2": 0.5}) == jg


def test_prismatic_lift_carries_the_whole_weight() -> None:
    joints = (
        ChainJoint("lift", "prismatic", "base", "carriage", axis=(0.0, 0.0, 1.0)),
        ChainJoint("arm", "revolute", "carriage", "arm", origin_xyz_m=(0.0, 0.0, 0.1), axis=(0.0, 1.0, 0.0)),
    )
    m = GravityModel(
        joints, (LinkInertial("carriage", 2.0), LinkInertial("arm", 1.0, (0.3, 0.0, 0.0))), "base"
    )
    np.testing.assert_allclose(gravity_torques(m, [0.05, 0.0]), [-3.0 * G, G * 0.3], atol=1e-12)
    with pytest.raises(InvalidCalibrationError, match="prismatic"):
        joint_gravity(m, "lift")


def test_branches_and_mimic_jaw_weigh_on_the_joints_above() -> None:
    doc = TWO_LINK.replace(
        "</robot>",
        """<link name="jaw"><inertial><origin xyz="0.1 0 0"/><mass value="0.2"/></inertial></link>
  <joint name="jaw_joint" type="revolute"><parent link="l1"/><child link="jaw"/><origin xyz="0.4 0 0"/>
    <axis xyz="0 1 0"/><mimic joint="j2"/><limit lower="-1" upper="1" effort="1" velocity="1"/></joint>
</robot>""",
    )
    m = gravity_model_from_urdf(UrdfDocument.from_bytes(doc))
    assert m.joint_names == ("j1", "j2")  # the mimic jaw is held: no column of its own
    t1, t2 = expected_two_link(0.0, 0.0)
    np.testing.assert_allclose(gravity_torques(m, [0.0, 0.0]), [t1 + 0.2 * G * 0.5, t2], atol=1e-12)


def _pe_gradient_pytransform3d(urdf: Path, names: tuple[str, ...], q: np.ndarray) -> np.ndarray:
    """−∂V/∂q by central differences of the potential energy, with pytransform3d's own URDF FK."""
    from pytransform3d.urdf import UrdfTransformManager

    text = urdf.read_text()
    masses = {
        el.get("name"): float(el.find("inertial/mass").get("value"))  # type: ignore[union-attr]
        for el in ET.fromstring(text).findall("link")
        if el.find("inertial") is not None
    }
    tm = UrdfTransformManager()
    tm.load_urdf(text)

    def potential(qv: np.ndarray) -> float:
        for n, v in zip(names, qv, strict=True):
            tm.set_joint(n, float(v))
        return sum(
            m * G * tm.get_transform(f"inertial_frame:{lk}", "base_link")[2, 3] for lk, m in masses.items()
        )

    h = 1e-6
    grad = []
    for k in range(len(names)):
        dq = np.zeros(len(names))
        dq[k] = h
        grad.append(-(potential(q + dq) - potential(q - dq)) / (2 * h))
    return np.array(grad)


@pytest.mark.slow
def test_so101_urdf_against_an_independent_fk() -> None:
    urdf = DATA / "so101_new_calib.urdf"
    m = gravity_model_from_urdf(urdf)
    assert set(m.joint_names) == set(SO101_JOINTS)
    assert m.total_mass_kg == pytest.approx(0.147 + 0.100006 + 0.103 + 0.104 + 0.079 + 0.087 + 1e-9 + 0.012)
    rng = np.random.default_rng(4)
    poses = rng.uniform(-1.5, 1.5, size=(3, 6))
    poses[:, m.joint_names.index("gripper")] = rng.uniform(
        0.0, 1.5, size=3
    )  # pytransform3d clips to the limits
    for q in [np.zeros(6), *poses]:
        ours = gravity_torques(m, q)
        np.testing.assert_allclose(ours, _pe_gradient_pytransform3d(urdf, m.joint_names, q), atol=2e-6)
    # the pan axis is vertical: gravity never turns it (to the rounding of the file's rpy)
    assert gravity_torques(m, rng.uniform(-1.5, 1.5, size=(5, 6)))[
        :, m.joint_names.index("shoulder_pan")
    ] == (
        pytest.approx(np.zeros(5), abs=1e-5)  # rpy rounded to 1.5708 in the file
    )
    # the shoulder holds the whole arm: more than half a newton-metre at the URDF zero (arm stretched out)
    assert gravity_torques(m, np.zeros(6))[m.joint_names.index("shoulder_lift")] == pytest.approx(
        0.5384, abs=1e-4
    )


def test_urdf_without_masses() -> None:
    assert gravity_model_if_any(DATA / "koch.urdf") is None
    with pytest.raises(FileFormatError, match="no link has an <inertial> with a positive mass"):
        gravity_model_from_urdf(DATA / "koch.urdf")
    assert gravity_model_if_any(DATA / "so101_new_calib.urdf") is not None


@pytest.mark.parametrize(
    ("inertial", "message"),
    [
        ('<inertial><mass value="-1"/></inertial>', "mass -1.0 is negative"),
        ('<inertial><mass value="nan"/></inertial>', "mass value"),
        ('<inertial><mass value="heavy"/></inertial>', "is not a number"),
        ("<inertial><origin xyz='0 0 0'/></inertial>", "needs <mass value"),
        ('<inertial><origin xyz="0 0"/><mass value="1"/></inertial>', "must have 3 numbers"),
    ],
)
def test_malformed_inertials_are_named(inertial: str, message: str) -> None:
    bad = TWO_LINK.replace('<link name="base"/>', f'<link name="base">{inertial}</link>')
    with pytest.raises(FileFormatError, match=message) as err:
        gravity_model_from_urdf(UrdfDocument.from_bytes(bad, "bad.urdf"))
    assert "bad.urdf" in str(err.value) and "'base'" in str(err.value)


def test_bad_inputs() -> None:
    m = two_link()
    with pytest.raises(ShapeMismatchError, match=r"expected \(N, 2\)"):
        gravity_torques(m, [0.0, 0.0, 0.0])
    with pytest.raises(JointMismatchError, match="no movable joint elbow"):
        gravity_torques(m, {"elbow": 1.0})
    with pytest.raises(InvalidCalibrationError, match="joint j2 is nan"):
        gravity_torques(m, {"j2": math.nan})
    with pytest.raises(JointMismatchError, match="no movable joint 'j9'"):
        joint_gravity(m, "j9")
    with pytest.raises(InvalidCalibrationError, match="mass must be"):
        LinkInertial("x", math.inf)
    floating = TWO_LINK.replace('name="j2" type="continuous"', 'name="j2" type="floating"')
    with pytest.raises(JointMismatchError, match="floating"):
        gravity_model_from_urdf(UrdfDocument.from_bytes(floating))
