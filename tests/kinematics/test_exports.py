"""Exports of an identified chain: the LeRobot export-urdf joint map and ur_description's kinematics YAML."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest
from tests.robots import UR_LINKS
from tests.ur.test_ur_urdf import ur_urdf_text

from robocal.backends.sim.kinematic_arm import SimulatedKinematicArm, hidden_errors
from robocal.cli.main import main
from robocal.core.chain import fk_chain
from robocal.core.jointmap import RobotCalibration
from robocal.core.kinematic_errors import ErrorModel
from robocal.core.kinematic_problem import Measurements
from robocal.formats import read_calibration, write_calibration
from robocal.formats.kinematic_data import measurements_to_csv
from robocal.formats.ur_kinematics import read_kinematics
from robocal.formats.urdf import read_urdf
from robocal.formats.urdf_chain import chain_from_urdf

from .conftest import JOINTS

TOOL = [0.0121, 0.0, -0.0981]
FIXTURES = Path(__file__).parents[1] / "fixtures" / "ur"


def _lerobot_map() -> RobotCalibration:
    """An export-urdf map of an SO-101 (LeRobot DEGREES: 2π/4095 rad per tick, mid of range at zero)."""
    k = 2 * math.pi / 4095
    names = [*JOINTS, "gripper"]
    return RobotCalibration(names, [1, -1, 1, 1, -1, 1], [2047.5, 2100.0, 1980.0, 2001.5, 2047.5, 2500.0], k)


@pytest.mark.slow
def test_joint_map_out_carries_the_offsets_and_the_urdf_leaves_them_out(
    points_session: Path, tmp_path: Path, capsys
) -> None:
    jm = _lerobot_map()
    ids = {n: i + 1 for i, n in enumerate(jm.joint_names)}
    write_calibration(tmp_path / "map.yaml", jm, "robocal", ids=ids)
    code = main(
        ["kinematics", "identify", "--urdf", str(points_session / "so101.urdf"), "--data", str(points_session / "points.csv"),
         "--tip-link", "gripper_link", "--tool-xyz", ",".join(map(str, TOOL)), "--out", str(tmp_path / "id.urdf"),
         "--report", str(tmp_path / "r.json"), "--joint-map", str(tmp_path / "map.yaml"),
         "--joint-map-out", str(tmp_path / "map_id.yaml")]
    )  # fmt: skip
    assert code in (0, 1)
    out_text = capsys.readouterr().out
    assert "(joint map with the zero offsets; the URDF leaves them out)" in out_text
    assert f"wrote {tmp_path / 'id.urdf'} (joint origins, the zero offsets in the joint map)" in out_text
    assert "folded in" not in out_text
    rep = json.loads((tmp_path / "r.json").read_text())
    out = read_calibration(tmp_path / "map_id.yaml")
    assert dict(out.ids) == ids
    new = out.calibration
    raw = np.random.default_rng(0).uniform(1200, 2900, (20, 6))
    q_old = jm.to_joint(raw)
    q_new = new.to_joint(raw)
    offsets = np.array([rep["joint_offsets"][n] for n in JOINTS])
    np.testing.assert_allclose(q_new[:, :5], q_old[:, :5] + offsets, atol=1e-12)
    np.testing.assert_array_equal(q_new[:, 5], q_old[:, 5])  # the gripper is not in the chain: unchanged
    assert np.abs(offsets).max() > math.radians(0.5)
    # URDF (offsets left out) fed with the new map's angles == the identified model fed with the old readings
    nominal = chain_from_urdf(read_urdf(points_session / "so101.urdf"), tip_link="gripper_link")
    T = np.eye(4)
    T[:3, 3] = TOOL
    model = ErrorModel(nominal, T_tip_tool=T)
    x = np.zeros(model.n_params)
    for p in rep["parameters"]:
        x[model.index(p["name"])] = p["estimate"]
    chain = chain_from_urdf(read_urdf(tmp_path / "id.urdf"), tip_link="gripper_link")
    tool = np.array([*rep["tool_xyz_m"], 1.0])
    p_urdf = (fk_chain(chain, q_new[:, :5]) @ tool)[:, :3]
    np.testing.assert_allclose(p_urdf, model.points(q_old[:, :5], x), atol=1e-12)


def test_joint_map_out_without_a_map_is_refused_and_nothing_written(
    points_session: Path, tmp_path: Path, capsys
) -> None:
    code = main(
        ["kinematics", "identify", "--urdf", str(points_session / "so101.urdf"), "--data", str(points_session / "points.csv"),
         "--tip-link", "gripper_link", "--out", str(tmp_path / "id.urdf"), "--joint-map-out", str(tmp_path / "m.yaml")]
    )  # fmt: skip
    assert code == 2
    assert "error: --joint-map-out needs the joint map the readings went through" in capsys.readouterr().err
    assert list(tmp_path.iterdir()) == []


def test_ur_yaml_of_an_identified_ur5e(tmp_path: Path, capsys) -> None:
    """ur_description's own ur5e default kinematics → URDF; a UR5e with hidden errors; the YAML reproduces it."""
    kin = read_kinematics(FIXTURES / "ur5e_default_kinematics.yaml")
    (tmp_path / "ur5e.urdf").write_text(ur_urdf_text(kin))
    chain = chain_from_urdf(read_urdf(tmp_path / "ur5e.urdf"), tip_link="tool0")
    T = np.eye(4)
    T[:3, 3] = [0.03, 0.02, 0.05]  # marker off the wrist-3 axis
    model = ErrorModel(chain, T_tip_tool=T)
    rng = np.random.default_rng(5)
    arm = SimulatedKinematicArm(model, hidden_errors(model, rng), ticks_per_turn=0)
    q = arm.sample_q(80, rng)
    data = Measurements("points", arm.read(q), arm.true_points(q))
    (tmp_path / "points.csv").write_text(measurements_to_csv(data, chain.joint_names))
    code = main(
        ["kinematics", "identify", "--urdf", str(tmp_path / "ur5e.urdf"), "--data", str(tmp_path / "points.csv"),
         "--tip-link", "tool0", "--tool-xyz", "0.03,0.02,0.05", "--ur-yaml", str(tmp_path / "ur5e_id.yaml"),
         "--ur-hash", "calib_12788084448423163542", "--report", str(tmp_path / "r.json")]
    )  # fmt: skip
    assert code in (0, 1), capsys.readouterr()
    written = read_kinematics(tmp_path / "ur5e_id.yaml")
    assert written.hash == "calib_12788084448423163542"
    assert [lk.name for lk in written.links] == list(UR_LINKS)
    # the YAML, put back into the URDF the way ur_description does, reproduces the true arm (noise-free data)
    (tmp_path / "ur5e_id.urdf").write_text(ur_urdf_text(written))
    identified = chain_from_urdf(read_urdf(tmp_path / "ur5e_id.urdf"), tip_link="tool0")
    rep = json.loads((tmp_path / "r.json").read_text())
    tool = np.array([*rep["tool_xyz_m"], 1.0])
    qv = arm.sample_q(200, rng)
    err = np.linalg.norm((fk_chain(identified, arm.read(qv)) @ tool)[:, :3] - arm.true_points(qv), axis=1)
    nominal = np.linalg.norm(model.points(qv) - arm.true_points(qv), axis=1)
    assert err.max() < 1e-6 < 1e-3 < nominal.mean()


def test_ur_yaml_needs_a_ur_chain(points_session: Path, tmp_path: Path, capsys) -> None:
    code = main(
        ["kinematics", "identify", "--urdf", str(points_session / "so101.urdf"), "--data", str(points_session / "points.csv"),
         "--tip-link", "gripper_link", "--ur-yaml", str(tmp_path / "k.yaml")]
    )  # fmt: skip
    assert code == 2
    assert "error: --ur-yaml needs a UR chain (shoulder_pan_joint" in capsys.readouterr().err
    assert not (tmp_path / "k.yaml").exists()


def test_corrected_urdf_keeps_the_text_of_every_number_that_stays(tmp_path: Path) -> None:
    """Only the numbers the fit changed are rewritten: ``0`` stays ``0`` (not ``0.0``), whole origins stay."""
    from robocal.formats.urdf import UrdfDocument

    src = (
        '<?xml version="1.0"?>\n<robot name="t">\n  <link name="a"/><link name="b"/><link name="c"/>\n'
        '  <joint name="j1" type="revolute"><parent link="a"/><child link="b"/>'
        '<origin xyz="0 0 0.1" rpy="0 0 0"/><axis xyz="0 0 1"/></joint>\n'
        '  <joint name="j2" type="revolute"><parent link="b"/><child link="c"/>'
        '<origin xyz="0.05 0 0" rpy="0 1.5708 0"/><axis xyz="0 1 0"/></joint>\n</robot>\n'
    )
    doc = UrdfDocument.from_bytes(src.encode())
    doc.set_origin("j1", (0.0, 0.0, 0.1), (0.0, 0.0, 0.0))  # nothing changed
    doc.set_origin("j2", (0.05, 0.0012, 0.0), (0.0, 1.5708, -0.003))  # y and yaw changed
    out = doc.to_bytes().decode()
    assert '<origin xyz="0 0 0.1" rpy="0 0 0"/>' in out
    assert '<origin xyz="0.05 0.0012 0" rpy="0 1.5708 -0.003"/>' in out
    assert out.replace('0.05 0.0012 0" rpy="0 1.5708 -0.003', '0.05 0 0" rpy="0 1.5708 0') == src
