"""The viewer's robot model: forward kinematics against yourdfpy, limits, mesh resolution and fallback."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("viser")  # robocal[view]; installed by the [test] extra
pytest.importorskip("yourdfpy")
pytest.importorskip("trimesh")
import trimesh
import yourdfpy
from hypothesis import given
from hypothesis import strategies as st
from tests.robots import SO101_JOINTS

from robocal.errors import FileFormatError, UsageError
from robocal.viewer import load_robot_model, parse_package_paths, resolve_mesh

from .conftest import REPO

KOCH = REPO / "src" / "robocal" / "data" / "koch.urdf"
SO101 = REPO / "src" / "robocal" / "data" / "so101_new_calib.urdf"

_koch_model = None


def koch() -> tuple[object, object]:
    """The viewer's Koch model (loaded once) and a fresh yourdfpy oracle.

    The oracle is loaded anew for every example (0.6 ms): a reused one keeps state between ``update_cfg`` calls,
    and hypothesis once saw it answer the same configuration differently on its first and second call
    (``FlakyFailure``, 3e-9 apart, with joint values of 1e-246 and 1e-45).
    """
    global _koch_model
    if _koch_model is None:
        _koch_model = load_robot_model(KOCH)
    return _koch_model, yourdfpy.URDF.load(str(KOCH), load_meshes=False, build_collision_scene_graph=False)


@given(st.lists(st.floats(-3.0, 3.0), min_size=6, max_size=6))
def test_forward_kinematics_matches_yourdfpy(q: list[float]) -> None:
    model, oracle = koch()
    assert model.actuated == ("joint1", "joint2", "joint3", "joint4", "joint5", "joint_gripper")
    oracle.update_cfg(dict(zip(model.actuated, q, strict=True)))
    world = model.link_poses(np.array(q))
    for link in model.links:
        expected = oracle.get_transform(link, model.root_link)
        # 1e-8: yourdfpy answered a joint angle of 2.3e-9 rad as exactly 0 (hypothesis found it in CI); the
        # model's sin(q) = 2.3e-9 is the right value, and 1e-8 m / rad still catches any real mistake
        np.testing.assert_allclose(world[link], expected, atol=1e-8)


def test_local_poses_compose_to_world(two_joint_urdf: Path) -> None:
    model = load_robot_model(two_joint_urdf)
    world, local = model.poses(np.array([0.4, -0.7]))
    np.testing.assert_allclose(world["lower"], local["upper"] @ local["lower"], atol=1e-12)
    # elbow at z 0.1 + 0.2·cos(0.4) above the base, rotated about y by 0.4 + 0.3 − 0.7 = 0
    np.testing.assert_allclose(world["lower"][:3, :3], np.eye(3), atol=1e-12)
    np.testing.assert_allclose(
        world["lower"][:3, 3], [0.2 * math.sin(0.4), 0, 0.1 + 0.2 * math.cos(0.4)], atol=1e-12
    )


def test_limits_and_outside(two_joint_urdf: Path) -> None:
    model = load_robot_model(two_joint_urdf)
    np.testing.assert_array_equal(model.lower, [-1.0, -2.0])
    np.testing.assert_array_equal(model.upper, [1.0, 0.5])
    assert model.outside_limits([1.0001, 0.5]).tolist() == [True, False]
    assert model.outside_limits([math.nan, -2.1]).tolist() == [False, True]
    assert model.warnings == []
    assert [(s.link, s.kind) for s in model.shapes] == [
        ("base", "fallback"),
        ("base", "fallback"),
        ("upper", "box"),
        ("lower", "cylinder"),
    ]


def test_missing_meshes_fall_back_with_one_warning() -> None:
    model = load_robot_model(SO101)
    assert len(model.warnings) == 1
    assert model.warnings[0].startswith("17 mesh(es) of so101_new_calib.urdf could not be loaded")
    assert "--package-path" in model.warnings[0]
    assert {s.kind for s in model.shapes} == {"fallback"}
    assert model.actuated == SO101_JOINTS


def _mesh_urdf(tmp_path: Path, filename: str) -> Path:
    p = tmp_path / "robot" / "urdf" / "m.urdf"
    p.parent.mkdir(parents=True)
    p.write_text(
        f"""<robot name="m"><link name="a"/><link name="b"><visual><geometry>
        <mesh filename="{filename}" scale="2 2 2"/></geometry></visual></link>
        <joint name="j" type="continuous"><parent link="a"/><child link="b"/><axis xyz="0 0 1"/></joint></robot>"""
    )
    return p


def test_package_mesh_resolves_through_package_path(tmp_path: Path) -> None:
    pkg = tmp_path / "pkgdir"
    (pkg / "meshes").mkdir(parents=True)
    trimesh.creation.box(extents=(0.1, 0.2, 0.3)).export(pkg / "meshes" / "b.stl")
    urdf = _mesh_urdf(tmp_path, "package://my_robot/meshes/b.stl")
    # not found without the package path: one warning, simple shapes
    lost = load_robot_model(urdf)
    assert len(lost.warnings) == 1 and "package://my_robot/meshes/b.stl" in lost.warnings[0]
    found = load_robot_model(urdf, parse_package_paths([f"my_robot={pkg}"]))
    assert found.warnings == []
    mesh = [s for s in found.shapes if s.kind == "mesh"]
    assert len(mesh) == 1
    np.testing.assert_allclose(mesh[0].vertices.max(axis=0) - mesh[0].vertices.min(axis=0), [0.2, 0.4, 0.6])
    assert found.lower[0] == -math.inf and found.upper[0] == math.inf  # continuous


def test_relative_mesh_next_to_urdf_and_package_layout(tmp_path: Path) -> None:
    urdf = _mesh_urdf(tmp_path, "../meshes/b.stl")
    (tmp_path / "robot" / "meshes").mkdir()
    trimesh.creation.box(extents=(0.1, 0.1, 0.1)).export(tmp_path / "robot" / "meshes" / "b.stl")
    assert load_robot_model(urdf).warnings == []
    # package:// without --package-path: the URDF's parent folder is the package root
    assert (
        resolve_mesh("package://robot/meshes/b.stl", urdf.parent, {})
        == urdf.parent.parent / "meshes" / "b.stl"
    )


def test_damaged_mesh_falls_back(tmp_path: Path) -> None:
    urdf = _mesh_urdf(tmp_path, "b.stl")
    (urdf.parent / "b.stl").write_bytes(b"solid nothing\nendsolid\n")
    model = load_robot_model(urdf)
    assert len(model.warnings) == 1 and "b.stl" in model.warnings[0]
    assert {s.kind for s in model.shapes} == {"fallback"}


@pytest.mark.parametrize(
    ("text", "needle"),
    [
        ("<robot name='x'><link name='a'/>", "URDF"),
        ("<robot name='x'><link name='a'/><link name='b'/></robot>", "one root link"),
        ("<robot name='x'><link name='a'/></robot>", "no movable joints"),
    ],
)
def test_bad_urdf_is_a_file_format_error(tmp_path: Path, text: str, needle: str) -> None:
    p = tmp_path / "bad.urdf"
    p.write_text(text)
    with pytest.raises(FileFormatError, match=needle):
        load_robot_model(p)


@pytest.mark.parametrize("item", ["nodir", "=x", "pkg="])
def test_package_path_needs_name_and_dir(item: str) -> None:
    with pytest.raises(UsageError, match="NAME=DIR"):
        parse_package_paths([item])


def test_package_path_must_exist(tmp_path: Path) -> None:
    with pytest.raises(UsageError, match="is not a folder"):
        parse_package_paths([f"p={tmp_path / 'missing'}"])


def test_loop_of_joints_is_refused(tmp_path: Path) -> None:
    p = tmp_path / "loop.urdf"
    p.write_text(
        """<robot name="x"><link name="a"/><link name="b"/><link name="c"/>
        <joint name="j1" type="continuous"><parent link="a"/><child link="b"/></joint>
        <joint name="j2" type="continuous"><parent link="b"/><child link="c"/></joint>
        <joint name="j3" type="continuous"><parent link="c"/><child link="b"/></joint></robot>"""
    )
    with pytest.raises(FileFormatError):
        load_robot_model(p)


def test_actuated_joints_in_tree_order() -> None:
    model = load_robot_model(SO101)  # the file lists the gripper first
    assert model.actuated[0] == "shoulder_pan" and model.actuated[-1] == "gripper"
