"""``robocal kinematics simulate|identify`` and ``demo --identify``: files, exit codes, bad data, no partial writes."""

from __future__ import annotations

import json
import re
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from robocal.cli.main import main
from robocal.core.chain import fk_chain
from robocal.core.kinematic_problem import Measurements
from robocal.errors import FileFormatError
from robocal.formats.kinematic_data import measurements_to_csv, parse_measurements
from robocal.formats.urdf import read_urdf
from robocal.formats.urdf_chain import chain_from_urdf

from .conftest import JOINTS, simulate
from .conftest import identify_cli as _identify

TOOL = "0.0121,0,-0.0981"


@pytest.mark.slow
def test_identify_writes_a_urdf_that_reproduces_the_fit(points_session: Path, tmp_path: Path, capsys) -> None:
    code = _identify(points_session, points_session / "points.csv", tmp_path, "--dh")
    out = capsys.readouterr().out
    assert code in (0, 1)
    rep = json.loads((tmp_path / "report.json").read_text())
    assert rep["rank"] == 23 and rep["poses"] == {"fit": 45, "validation": 15}
    assert rep["errors_mm"]["validation"]["corrected"]["mean"] < 1.2  # vs noisy markers (0.5 mm per axis)
    assert rep["errors_mm"]["validation"]["nominal"]["mean"] > 5.0
    assert rep["dh_like"]["held_joints"] == ["elbow_flex", "wrist_flex"]
    assert "DH is biased on parallel-axis arms" in out
    assert "rank 23 of 41 unknowns" in out
    # the corrected URDF with the nominal tool gives the identified model's points from the same readings
    chain = chain_from_urdf(read_urdf(tmp_path / "id.urdf"), tip_link="gripper_link")
    tool = np.array(rep["tool_xyz_m"] + [1.0])
    q = np.random.default_rng(0).uniform(-1, 1, (10, 5))
    p_urdf = (fk_chain(chain, q) @ tool)[:, :3]
    nominal = chain_from_urdf(read_urdf(points_session / "so101.urdf"), tip_link="gripper_link")
    assert np.abs(p_urdf - (fk_chain(nominal, q) @ tool)[:, :3]).max() > 1e-3  # it did change
    from robocal.core.kinematic_errors import ErrorModel

    T = np.eye(4)
    T[:3, 3] = [0.0121, 0, -0.0981]
    model = ErrorModel(nominal, T_tip_tool=T)
    x = np.zeros(model.n_params)
    for p in rep["parameters"]:
        if p["name"] in model.names:
            x[model.index(p["name"])] = p["estimate"]
    np.testing.assert_allclose(p_urdf, model.points(q, x), atol=1e-12)
    # only the five chain joints' <origin> lines differ from the original file
    a = (points_session / "so101.urdf").read_text().splitlines()
    b = (tmp_path / "id.urdf").read_text().splitlines()
    changed = [i for i, (x1, x2) in enumerate(zip(a, b, strict=True)) if x1 != x2]
    assert len(changed) == 5 and all("<origin xyz=" in b[i] for i in changed)


def _rewrite(src: Path, dst: Path, row: int, col: str, value: str) -> Path:
    lines = src.read_text().splitlines()
    header = lines[0].split(",")
    cells = lines[row].split(",")
    cells[header.index(col)] = value
    lines[row] = ",".join(cells)
    dst.write_text("\n".join(lines) + "\n")
    return dst


@pytest.mark.parametrize(
    ("col", "value", "message"),
    [
        ("x", "nan", "line 4: column 'x' is 'nan'; values must be finite"),
        ("elbow_flex", "abc", "line 4: column 'elbow_flex' is 'abc', not a number"),
        ("elbow_flex", "2.5", "pose 3: joint elbow_flex = 2.5 is outside its limits [-1.69, 1.69]"),
    ],
)
def test_bad_pose_is_one_error_line_and_no_file(points_session, tmp_path, capsys, col, value, message) -> None:
    bad = _rewrite(points_session / "points.csv", tmp_path / "bad.csv", 3, col, value)
    assert _identify(points_session, bad, tmp_path) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith("error: ") and message in err
    assert not (tmp_path / "id.urdf").exists() and not (tmp_path / "report.json").exists()


def test_too_few_poses_and_unreadable_file(points_session: Path, tmp_path: Path, capsys) -> None:
    few = tmp_path / "few.csv"
    few.write_text("\n".join((points_session / "points.csv").read_text().splitlines()[:10]) + "\n")
    assert _identify(points_session, few, tmp_path) == 2
    assert "too few poses" in capsys.readouterr().err
    assert _identify(points_session, tmp_path / "missing.csv", tmp_path) == 2
    err = capsys.readouterr().err
    assert "measurement file" in err and "missing.csv: no such file" in err
    (tmp_path / "bin.csv").write_bytes(b"\xff\xfe\x00garbage")
    assert _identify(points_session, tmp_path / "bin.csv", tmp_path) == 2
    assert "not UTF-8 text" in capsys.readouterr().err
    assert not (tmp_path / "id.urdf").exists()


def test_existing_output_is_kept_on_failure(points_session: Path, tmp_path: Path) -> None:
    (tmp_path / "id.urdf").write_text("old")
    bad = _rewrite(points_session / "points.csv", tmp_path / "bad.csv", 2, "y", "inf")
    assert _identify(points_session, bad, tmp_path) == 2
    assert (tmp_path / "id.urdf").read_text() == "old"


@pytest.mark.slow
def test_marker_on_axis_is_reported_as_a_warning(tmp_path: Path, capsys) -> None:
    assert simulate(tmp_path, "--on-axis", "--poses", "40") == 0
    capsys.readouterr()
    code = main(
        [
            "kinematics",
            "identify",
            "--urdf",
            str(tmp_path / "so101.urdf"),
            "--data",
            str(tmp_path / "points.csv"),
            "--tip-link",
            "gripper_link",
            "--tool-xyz",
            "0,0,-0.0981",
        ]
    )
    captured = capsys.readouterr()
    assert code == 1
    assert "rank 21" in captured.out
    assert "warning: wrist_roll.offset: the marker is on the wrist_roll axis" in captured.err


def test_tracker_frame_is_registered(points_session: Path, tmp_path: Path, capsys) -> None:
    lines = (points_session / "points.csv").read_text().splitlines()
    header = lines[0].split(",")
    ix = [header.index(c) for c in "xyz"]
    c, s = np.cos(0.7), np.sin(0.7)
    R = np.array([[c, -s, 0], [s, c, 0], [0, 0, 1.0]])
    out = [lines[0]]
    for line in lines[1:]:
        cells = line.split(",")
        p = R @ np.array([float(cells[i]) for i in ix]) + [1.2, -0.4, 0.3]
        for i, v in zip(ix, p, strict=True):
            cells[i] = repr(float(v))
        out.append(",".join(cells))
    (tmp_path / "tracker.csv").write_text("\n".join(out) + "\n")
    assert _identify(points_session, tmp_path / "tracker.csv", tmp_path, "--frame", "tracker") in (0, 1)
    rep = json.loads((tmp_path / "report.json").read_text())
    assert rep["errors_mm"]["validation"]["corrected"]["mean"] < 1.2
    np.testing.assert_allclose(np.array(rep["T_world_base"])[:3, 3], [1.2, -0.4, 0.3], atol=5e-3)


@pytest.mark.slow
@pytest.mark.parametrize("kind", ["touch", "gauge"])
def test_touch_and_gauge_sessions_from_the_cli(tmp_path: Path, capsys, kind: str) -> None:
    assert simulate(tmp_path, "--kind", kind, "--poses", "14") == 0
    capsys.readouterr()
    args = [
        "kinematics",
        "identify",
        "--urdf",
        str(tmp_path / "so101.urdf"),
        "--data",
        str(tmp_path / f"{kind}.csv"),
        "--kind",
        kind,
        "--tip-link",
        "gripper_link",
        "--tool-xyz",
        TOOL,
        "--report",
        str(tmp_path / "r.json"),
    ]
    if kind == "gauge":
        args += ["--gauge-mm", "50"]
    assert main(args) in (0, 1)
    rep = json.loads((tmp_path / "r.json").read_text())
    assert rep["errors_mm"]["validation"]["corrected"]["max"] < 0.5  # quantisation only
    if kind == "gauge":
        a, b = (np.array(rep["contact_groups"][k]) for k in "AB")
        assert np.linalg.norm(a - b) == pytest.approx(0.05, abs=2e-6)
    else:
        assert sorted(rep["contact_groups"]) == ["P1", "P2", "P3"]
        assert any("overall size" in u["reason"] for u in rep["unidentifiable"])


def test_gauge_needs_distance(points_session: Path, capsys) -> None:
    assert (
        main(
            [
                "kinematics",
                "identify",
                "--urdf",
                str(points_session / "so101.urdf"),
                "--data",
                str(points_session / "points.csv"),
                "--kind",
                "gauge",
                "--tip-link",
                "gripper_link",
            ]
        )
        == 2
    )
    assert "--gauge-mm" in capsys.readouterr().err


@pytest.mark.slow
def test_demo_identify(capsys) -> None:
    from tests.foundation.test_readme_commands import demo_nominal_error_mm

    assert main(["demo", "--robot", "koch", "--identify"]) in (0, 1)
    out = capsys.readouterr().out
    assert "against the hidden truth: the 17 held-out poses mean " in out
    assert "fit poses (50): nominal" in out and "validation poses (17): nominal" in out
    mean = float(out.split("→ identified mean ")[1].split(" mm")[0])  # on 500 new poses
    assert mean < 0.6
    # the nominal error the README quotes for the SO-101 is computed the way the demo computes it
    assert f"500 new poses: nominal mean {demo_nominal_error_mm('koch', 0):.2f} mm →" in out
    # progress as each step starts, before any result (the whole demo takes a minute or two)
    steps = re.findall(r"^step (\d)/2: (.*) \(\d+ s\)$", out, flags=re.M)
    assert steps == [
        ("1", "simulating 50 planned poses and 17 held-out ones, then identifying (analysis, fit, DH-like fit)"),
        ("2", "checking the identified model against the hidden truth on 500 new poses"),
    ]
    assert out.index("step 2/2: ") < out.index("fit poses (50): nominal")
    assert main(["demo", "--robot", "lite", "--identify"]) == 2


def test_reader_units_columns_and_errors() -> None:
    text = (
        "# tracker export\npose,shoulder_pan_deg,shoulder_lift,elbow_flex,wrist_flex,wrist_roll,x_mm,y_mm,z_mm\n"
        "1,90,0,0,0,0,100,200,300\n"
    )
    m, labels = parse_measurements(text, "points", JOINTS)
    assert labels == () and m.q_rad[0, 0] == pytest.approx(np.pi / 2)
    np.testing.assert_allclose(m.p_world_m[0], [0.1, 0.2, 0.3])
    with pytest.raises(FileFormatError, match="unknown columns shoulder_pann"):
        parse_measurements(
            text.replace("shoulder_pan_deg", "shoulder_pan,shoulder_pann").replace("1,90", "1,0,90"),
            "points",
            JOINTS,
        )
    with pytest.raises(FileFormatError, match="missing columns wrist_roll"):
        parse_measurements("shoulder_pan,shoulder_lift,elbow_flex,wrist_flex,x,y,z\n", "points", JOINTS)
    with pytest.raises(FileFormatError, match="socket is 'C'; expected A or B"):
        parse_measurements(
            "shoulder_pan,shoulder_lift,elbow_flex,wrist_flex,wrist_roll,socket\n0,0,0,0,0,C\n",
            "gauge",
            JOINTS,
            distance_m=0.05,
        )


@given(st.integers(1, 8), st.sampled_from(["points", "touch", "gauge"]), st.integers(0, 2**31))
def test_csv_round_trip_is_exact(n: int, kind: str, seed: int) -> None:
    rng = np.random.default_rng(seed)
    q = rng.uniform(-2, 2, (2 * n, 5))
    if kind == "points":
        m = Measurements("points", q, rng.normal(0, 0.3, (2 * n, 3)))
    else:
        m = Measurements(kind, q, group=np.arange(2 * n) % 2, distance_m=0.05 if kind == "gauge" else None)
    back, _ = parse_measurements(
        measurements_to_csv(m, JOINTS, ("P1", "P2")), kind, JOINTS, distance_m=m.distance_m
    )
    np.testing.assert_array_equal(back.q_rad, m.q_rad)
    if kind == "points":
        np.testing.assert_array_equal(back.p_world_m, m.p_world_m)
    else:
        np.testing.assert_array_equal(back.group, m.group)


@pytest.mark.slow
def test_plan_writes_poses_inside_the_limits(tmp_path: Path, capsys) -> None:
    from robocal.workflows.kinematics.sim import shipped_urdf

    out = tmp_path / "plan.csv"
    args = [
        "kinematics",
        "plan",
        "--urdf",
        str(shipped_urdf("so101")),
        "--tip-link",
        "gripper_link",
        "--tool-xyz",
        TOOL,
        "--poses",
        "30",
        "--out",
        str(out),
    ]
    assert main(args) == 0
    assert (
        "30 poses (I-optimal of 2000 candidates) for shoulder_pan, shoulder_lift, elbow_flex, wrist_flex, "
        "wrist_roll: rank 23"
        in capsys.readouterr().out
    )
    lines = out.read_text().splitlines()
    assert lines[0] == "pose," + ",".join(JOINTS) and len(lines) == 31
    q = np.array([[float(v) for v in line.split(",")[1:]] for line in lines[1:]])
    chain = chain_from_urdf(read_urdf(shipped_urdf("so101")), tip_link="gripper_link")
    chain.check_q(q)  # raises if any pose is outside the limits
    # on the wrist-roll axis the plan still writes, with a warning naming the cause
    assert main([*args[:-4], "--tool-xyz", "0,0,-0.0981", "--poses", "30", "--out", str(out)]) == 1
    assert "the marker is on the wrist_roll axis" in capsys.readouterr().err
    assert main([*args[:-2], "--out", str(tmp_path / "nofolder" / "p.csv")]) == 2


@pytest.mark.slow
def test_prior_options_reach_the_fit_and_the_report(points_session: Path, tmp_path: Path, capsys) -> None:
    assert _identify(points_session, points_session / "points.csv", tmp_path, "--prior-mm", "2", "--prior-offset-deg", "3") in (0, 1)
    rep = json.loads((tmp_path / "report.json").read_text())
    prior = dict(rep["fit"]["prior"])
    assert prior.pop("noise_mm") is None
    assert prior == pytest.approx({"length_mm": 2.0, "angle_deg": 0.5, "offset_deg": 3.0})
    assert rep["fit"]["method"] == "lm"
    # every parameter is estimated with the prior: the ones outside the base set get an estimate and a σ too
    outside = [p for p in rep["parameters"] if not p["identified"]]
    assert outside and all(p["sigma"] is not None and p["sigma"] > 0 for p in outside)
    assert rep["errors_mm"]["validation"]["corrected"]["mean"] < 1.2
    plain = tmp_path / "plain"
    plain.mkdir()
    assert _identify(points_session, points_session / "points.csv", plain) in (0, 1)
    rep0 = json.loads((plain / "report.json").read_text())
    assert rep0["fit"]["prior"] is None
    assert all(p["sigma"] is None for p in rep0["parameters"] if not p["identified"])


@pytest.mark.parametrize("flag", ["--prior-mm", "--prior-deg", "--prior-offset-deg"])
def test_bad_prior_sigma_is_one_error_line(points_session: Path, tmp_path: Path, capsys, flag: str) -> None:
    assert _identify(points_session, points_session / "points.csv", tmp_path, flag, "0") == 2
    err = capsys.readouterr().err
    assert err.strip() == f"error: {flag} must be a positive number, got 0.0"
    assert not (tmp_path / "id.urdf").exists() and not (tmp_path / "report.json").exists()
