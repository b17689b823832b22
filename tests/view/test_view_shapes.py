"""Simple-shape URDFs: the generator keeps the joints, and the shipped files are what it makes."""

from __future__ import annotations

import math
import os
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("viser")  # robocal[view]; installed by the [test] extra
pytest.importorskip("yourdfpy")
pytest.importorskip("trimesh")

from robocal.formats.urdf import parse_urdf
from robocal.viewer import load_robot_model
from robocal.viewer.shapes import add_simple_shapes

from .conftest import REPO

DATA = REPO / "src" / "robocal" / "data"
SHIPPED = {
    "lite_bimanual_shapes.urdf": (
        REPO / "examples" / "lite" / "lite_bimanual.urdf",
        "Berkeley Humanoid Lite bimanual arms: examples/lite/lite_bimanual.urdf with simple-shape visuals "
        "(robocal.viewer.shapes.add_simple_shapes), for robocal view and its demo. Regenerate with "
        "tests/view/test_view_shapes.py.",
    ),
    "so101_shapes.urdf": (
        DATA / "so101_new_calib.urdf",
        "SO-101 follower: so101_new_calib.urdf (TheRobotStudio/SO-ARM100, Apache-2.0) with its mesh visuals "
        "replaced by simple shapes (robocal.viewer.shapes.add_simple_shapes), for robocal view without the mesh "
        "files. Regenerate with tests/view/test_view_shapes.py.",
    ),
}


@pytest.mark.parametrize("name", sorted(SHIPPED))
def test_shipped_shape_urdfs_are_generated(name: str) -> None:
    source, comment = SHIPPED[name]
    made = add_simple_shapes(source.read_text(), comment=comment)
    if os.environ.get("ROBOCAL_REGENERATE") == "1":
        (DATA / name).write_text(made)
    assert (DATA / name).read_text() == made
    original, shaped = parse_urdf(source.read_text()), parse_urdf(made)
    assert shaped.joints == original.joints and shaped.joint_params == original.joint_params
    model = load_robot_model(DATA / name)
    assert model.warnings == [] and {s.kind for s in model.shapes} == {"sphere", "cylinder"}


def test_cylinders_reach_the_child_joints(tmp_path: Path) -> None:
    p = tmp_path / "s.urdf"
    p.write_text(
        add_simple_shapes(
            """<robot name="r"><link name="a"/><link name="b"/>
            <joint name="j" type="revolute"><parent link="a"/><child link="b"/><origin xyz="0.1 -0.2 0.3"/>
            <axis xyz="0 0 1"/><limit lower="-1" upper="1" effort="1" velocity="1"/></joint></robot>"""
        )
    )
    model = load_robot_model(p)
    rods = [s for s in model.shapes if s.kind == "cylinder"]
    assert len(rods) == 1 and rods[0].link == "a"
    v = rods[0].vertices
    # the rod's axis runs from the link origin to the joint origin (0.1, −0.2, 0.3), radius 15 mm
    d = np.array([0.1, -0.2, 0.3])
    along = v @ d / np.linalg.norm(d)
    assert along.min() == pytest.approx(0.0, abs=1e-6) and along.max() == pytest.approx(
        math.sqrt(0.14), abs=1e-6
    )
    radial = np.linalg.norm(v - np.outer(along, d / np.linalg.norm(d)), axis=1)
    assert radial.max() == pytest.approx(0.015, abs=1e-6)
