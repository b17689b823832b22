"""YAML → URDF → FK through an independent URDF reader (pytransform3d), and in-place URDF origin edits."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given
from lxml import etree
from pytransform3d.urdf import UrdfTransformManager

from robocal.core.dh import DHParameters, fk_dh
from robocal.core.se3 import rotation_angle_between
from robocal.core.ur import JOINT_NAMES, UrKinematics, correct_kinematics
from robocal.formats.ur_kinematics import read_kinematics, update_urdf_origins, write_kinematics
from robocal.workflows.ur.verify import urdf_fk

from .test_ur_core import make_realistic, realistic

LINKS = (
    "base_link_inertia",
    "shoulder_link",
    "upper_arm_link",
    "forearm_link",
    "wrist_1_link",
    "wrist_2_link",
    "wrist_3_link",
)


def ur_urdf_text(kin: UrKinematics) -> str:
    """An expanded URDF laid out like ur_description's ur_macro.xacro, origins from the kinematics YAML."""
    parts = [
        '<?xml version="1.0"?>',
        "<!-- UR arm (test) -->",
        '<robot name="ur">',
        '  <link name="base_link"/>',
    ]
    parts += [f'  <link name="{name}"/>' for name in LINKS]
    parts += ['  <link name="flange"/>', '  <link name="tool0"/>']
    parts.append(
        '  <joint name="base_link-base_link_inertia" type="fixed"><parent link="base_link"/>'
        '<child link="base_link_inertia"/><origin xyz="0 0 0" rpy="0 0 3.141592653589793"/></joint>'
    )
    for k, (joint, link) in enumerate(zip(JOINT_NAMES, kin.links, strict=True)):
        xyz = " ".join(repr(v) for v in link.xyz_m)
        rpy = " ".join(repr(v) for v in link.rpy_rad)
        parts.append(
            f'  <joint name="{joint}" type="revolute"><parent link="{LINKS[k]}"/><child link="{LINKS[k + 1]}"/>'
            f'<origin xyz="{xyz}" rpy="{rpy}"/><axis xyz="0 0 1"/>'
            '<limit lower="-7.0" upper="7.0" effort="1" velocity="1"/></joint>'
        )
    parts.append(
        '  <joint name="wrist_3-flange" type="fixed"><parent link="wrist_3_link"/><child link="flange"/>'
        '<origin xyz="0 0 0" rpy="0 -1.5707963267948966 -1.5707963267948966"/></joint>'
    )
    parts.append(
        '  <joint name="flange-tool0" type="fixed"><parent link="flange"/><child link="tool0"/>'
        '<origin xyz="0 0 0" rpy="1.5707963267948966 0 1.5707963267948966"/></joint>'
    )
    parts.append(
        '  <ros2_control name="UR" type="system"><hardware><plugin>ur/UR</plugin></hardware>'
        '<joint name="elbow_joint"><param name="initial_position">0.0</param></joint></ros2_control>'
    )
    parts.append("</robot>")
    return "\n".join(parts) + "\n"


def pytransform3d_fk(kin: UrKinematics, q: np.ndarray) -> np.ndarray:
    tm = UrdfTransformManager()
    tm.load_urdf(ur_urdf_text(kin))
    out = np.empty((q.shape[0], 4, 4))
    for i, qi in enumerate(q):
        for name, v in zip(JOINT_NAMES, qi, strict=True):
            tm.set_joint(name, float(v))
        out[i] = tm.get_transform("tool0", "base_link_inertia")
    return out


def errors(T: np.ndarray, T_ref: np.ndarray) -> tuple[float, float]:
    pos = float(np.max(np.linalg.norm(T[:, :3, 3] - T_ref[:, :3, 3], axis=1)))
    rot = float(np.max(rotation_angle_between(T[:, :3, :3], T_ref[:, :3, :3])))
    return pos, rot


@pytest.mark.slow
def test_yaml_to_urdf_fk_equals_dh_fk(tmp_path: Path, test_set: tuple[int, DHParameters]) -> None:
    set_id, dh = test_set
    out = tmp_path / "cal.yaml"
    write_kinematics(out, correct_kinematics(dh, "urdf"))
    kin = read_kinematics(out)  # through the file, like ur_description
    q = np.random.default_rng(set_id).uniform(-2 * math.pi, 2 * math.pi, (200, 6))
    pos, rot = errors(pytransform3d_fk(kin, q), fk_dh(dh, q))
    assert pos <= 1e-10
    assert rot <= 1e-10


@pytest.mark.slow
def test_upstream_yaml_through_urdf_is_off_by_tens_of_micrometres(dh_sets: dict[int, DHParameters]) -> None:
    kin = correct_kinematics(dh_sets[1], "upstream")
    q = np.random.default_rng(1).uniform(-2 * math.pi, 2 * math.pi, (300, 6))
    pos, rot = errors(pytransform3d_fk(kin, q), fk_dh(dh_sets[1], q))
    assert 1e-5 < pos < 4.4e-5  # the reference measured up to 4.3e-5 m for set 1
    assert 4e-5 < rot < 6.3e-5


@pytest.mark.slow
@given(realistic)
def test_hypothesis_yaml_to_urdf_fk(params: tuple) -> None:  # type: ignore[type-arg]
    dh = make_realistic(params)
    q = np.random.default_rng(2).uniform(-2 * math.pi, 2 * math.pi, (5, 6))
    pos, rot = errors(pytransform3d_fk(correct_kinematics(dh), q), fk_dh(dh, q))
    assert pos <= 1e-10
    assert rot <= 1e-10


def test_update_urdf_origins_in_place_keeps_comments_and_ros2_control(
    tmp_path: Path, dh_sets: dict[int, DHParameters]
) -> None:
    nominal_kin = correct_kinematics(DHParameters((0,) * 6, (0,) * 6, (0.1,) * 6, (0,) * 6))
    src = tmp_path / "ur.urdf"
    src.write_text(ur_urdf_text(nominal_kin))
    kin = correct_kinematics(dh_sets[3])
    dst = tmp_path / "ur_calibrated.urdf"
    update_urdf_origins(src, dst, kin)
    text = dst.read_text()
    assert "<!-- UR arm (test) -->" in text
    assert '<param name="initial_position">0.0</param>' in text
    root = etree.fromstring(dst.read_bytes())
    assert [j.get("name") for j in root.findall("joint")][1:7] == list(JOINT_NAMES)
    elbow = root.find("joint[@name='elbow_joint']/origin")
    assert elbow is not None
    assert [float(v) for v in elbow.get("xyz").split()] == list(kin.links[2].xyz_m)
    q = np.random.default_rng(4).uniform(-6, 6, (100, 6))
    pos, rot = errors(urdf_fk(dst, q), fk_dh(dh_sets[3], q))
    assert pos <= 1e-10 and rot <= 1e-10
    assert src.read_text() == ur_urdf_text(nominal_kin)  # input untouched


def test_update_urdf_missing_joint_writes_nothing(tmp_path: Path, dh_sets: dict[int, DHParameters]) -> None:
    src = tmp_path / "bad.urdf"
    src.write_text(
        '<robot name="x"><link name="a"/><link name="b"/><joint name="shoulder_pan_joint" '
        'type="revolute"><parent link="a"/><child link="b"/><axis xyz="0 0 1"/></joint></robot>'
    )
    dst = tmp_path / "out.urdf"
    with pytest.raises(Exception, match="missing UR joint"):
        update_urdf_origins(src, dst, correct_kinematics(dh_sets[1]))
    assert not dst.exists()


def test_yaml_and_urdf_fk_are_one_chain_fk(tmp_path: Path, dh_sets: dict[int, DHParameters]) -> None:
    # both sides of `ur verify` evaluate the URDF chain through core.chain.fk_chain: a URDF whose origins come
    # from the YAML gives bit-identical wrist_3 poses, and the DH FK is the independent reference
    from robocal.core.chain import fk_chain
    from robocal.core.ur import fk_origins
    from robocal.formats.urdf import read_urdf
    from robocal.formats.urdf_chain import chain_from_urdf

    kin = correct_kinematics(dh_sets[3], "urdf")
    p = tmp_path / "ur.urdf"
    p.write_text(ur_urdf_text(kin))
    q = np.random.default_rng(5).uniform(-6.0, 6.0, (200, 6))
    chain = chain_from_urdf(read_urdf(p), "base_link_inertia", "wrist_3_link")
    assert chain.joint_names == JOINT_NAMES
    T_yaml = fk_origins(kin.xyz_array(), kin.rpy_array(), q)
    assert np.array_equal(fk_chain(chain, q), T_yaml)
    assert np.array_equal(
        urdf_fk(p, q)[:, :3, 3], T_yaml[:, :3, 3]
    )  # flange and tool0 sit at wrist_3's origin
    np.testing.assert_allclose(T_yaml[:, :3, 3], fk_dh(dh_sets[3], q)[:, :3, 3], rtol=0, atol=1e-9)
