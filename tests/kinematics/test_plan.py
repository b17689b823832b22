"""Pose planning (issue 13): greedy I-optimal selection in core, ``robocal kinematics plan`` and its bad input."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from robocal.backends.sim.kinematic_arm import SimulatedKinematicArm
from robocal.cli.main import main
from robocal.core.identifiability import select_poses, select_poses_i_optimal
from robocal.core.kinematic_problem import Measurements, Problem, analyse, free_indices, plan_poses
from robocal.errors import FileFormatError, UsageError
from robocal.formats.kinematic_data import parse_joint_table
from robocal.workflows.kinematics.fit import PriorSigmas
from robocal.workflows.kinematics.sim import shipped_urdf

from .conftest import so101_model

JOINTS = ("shoulder_pan", "shoulder_lift", "elbow_flex", "wrist_flex", "wrist_roll")
TOOL = "0.0121,0,-0.0981"


def _avg_variance(Jc: np.ndarray, W: np.ndarray, P: np.ndarray, rows: list[int]) -> float:
    A = P + sum((Jc[i].T @ Jc[i] for i in rows), np.zeros_like(P))
    return float(np.trace(W @ np.linalg.inv(A)))


def test_each_greedy_step_is_the_brute_force_best() -> None:
    rng = np.random.default_rng(4)
    Jc = rng.normal(size=(40, 3, 5))
    Jp = rng.normal(size=(25, 3, 5))
    prec = np.array([0.5, 1.0, 2.0, 0.1, 3.0])
    chosen = select_poses_i_optimal(Jc, 6, J_predict=Jp, prior_precision=prec)
    W = np.einsum("mrk,mrl->kl", Jp, Jp) / 25
    P = np.diag(prec)
    for step in range(6):
        before = chosen[:step].tolist()
        scores = [_avg_variance(Jc, W, P, [*before, i]) if i not in before else np.inf for i in range(40)]
        assert chosen[step] == int(np.argmin(scores))
    # without a prior the first poses are D-optimal until JᵀJ has full rank (5 unknowns, 3 rows a pose: 3)
    plain = select_poses_i_optimal(Jc, 6)
    np.testing.assert_array_equal(plain[:3], select_poses(Jc, 3))
    assert len(set(plain.tolist())) == 6
    with pytest.raises(UsageError, match="cannot select 41 poses from 40 candidates"):
        select_poses_i_optimal(Jc, 41)


@pytest.mark.slow
def test_i_optimal_plan_predicts_the_tool_point_better_than_d_optimal() -> None:
    model = so101_model()
    cand = SimulatedKinematicArm(model, np.zeros(model.n_params)).sample_q(600, np.random.default_rng(7))
    problem = Problem(
        model,
        Measurements("points", cand, model.points(cand)),
        free_indices(model, ["base"]),
        np.zeros(model.n_params),
    )
    ident = analyse(problem)
    _, J = problem.residuals_and_jacobian(problem.initial_theta())
    Jb = J[:, list(ident.base)].reshape(600, 3, -1)
    W = np.einsum("mrk,mrl->kl", Jb, Jb) / 600
    zero = np.zeros((Jb.shape[2], Jb.shape[2]))
    i_plan = plan_poses(model, cand, 30, criterion="I").tolist()
    d_plan = plan_poses(model, cand, 30, criterion="D").tolist()
    v_i, v_d = _avg_variance(Jb, W, zero, i_plan), _avg_variance(Jb, W, zero, d_plan)
    # the I-optimal plan is better on its own criterion (measured 0.705 against 0.721; 0.900 for 30 random poses)
    assert v_i < 0.99 * v_d
    assert v_d < 0.85 * _avg_variance(Jb, W, zero, list(range(30)))
    # the Bayesian plan differs and is also a valid plan of distinct poses
    b_plan = plan_poses(model, cand, 30, criterion="I", prior_sigma=PriorSigmas().model_sigmas(model))
    assert len(set(b_plan.tolist())) == 30 and b_plan.tolist() != i_plan
    with pytest.raises(UsageError, match="criterion 'G'"):
        plan_poses(model, cand, 30, criterion="G")
    with pytest.raises(UsageError, match="prior σ must be"):
        plan_poses(model, cand, 30, criterion="I", prior_sigma=np.ones(3))


def _plan(tmp_path: Path, *extra: str, out: Path | None = None) -> list[str]:
    return [
        "kinematics", "plan", "--urdf", str(shipped_urdf("so101")), "--tip-link", "gripper_link",
        "--tool-xyz", TOOL, "--out", str(out or tmp_path / "plan.csv"), *extra,
    ]  # fmt: skip


@pytest.mark.slow
def test_plan_criteria_and_frames(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(_plan(tmp_path, "--poses", "25", "--candidates", "500")) == 0
    out = capsys.readouterr().out
    assert "25 poses (I-optimal of 500 candidates)" in out and "rank 23" in out
    sigma_i = float(out.split("predicted tool-point σ ")[1].split(" mm")[0])
    assert 0.2 < sigma_i < 0.8
    assert main(_plan(tmp_path, "--poses", "25", "--candidates", "500", "--criterion", "d")) == 0
    out = capsys.readouterr().out
    assert "25 poses (D-optimal of 500 candidates)" in out
    assert float(out.split("predicted tool-point σ ")[1].split(" mm")[0]) > sigma_i
    d_plan = (tmp_path / "plan.csv").read_text()
    # a tracker frame: the base pose (registration) is estimated too; it takes over the first joint's origin
    assert main(_plan(tmp_path, "--poses", "25", "--candidates", "500", "--frame", "tracker")) == 0
    assert "rank 23" in capsys.readouterr().out and (tmp_path / "plan.csv").read_text() != d_plan
    assert main(_plan(tmp_path, "--poses", "25", "--candidates", "500", "--prior")) == 0
    lines = (tmp_path / "plan.csv").read_text().splitlines()
    assert lines[0] == "pose," + ",".join(JOINTS) and len(lines) == 26


@pytest.mark.parametrize(
    ("extra", "message"),
    [
        (
            ("--poses", "7"),
            "too few poses: 7 poses give 21 equations, not more than the 23 parameters the candidates can identify; plan at least 9 poses",
        ),
        (("--poses", "0"), "--poses must be at least 1, got 0"),
        (("--kind", "foo"), "--kind 'foo'; valid: points, touch, gauge, tag"),
        (("--criterion", "a"), "--criterion 'a'; valid: i, d"),
        (("--criterion", "d", "--prior"), "a prior applies to the I-optimal plan"),
        (("--frame", "camera"), "--frame 'camera'; valid: base, tracker"),
        (("--noise-mm", "nan"), "--noise-mm must be a positive number"),
        (("--poses", "60", "--candidates", "50"), "--poses 60: only 50 candidate poses to choose from"),
    ],
)
def test_bad_options_write_nothing(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], extra: tuple[str, ...], message: str
) -> None:
    out = tmp_path / "plan.csv"
    out.write_text("old\n")
    assert main(_plan(tmp_path, *extra)) == 2
    err = capsys.readouterr().err
    assert message in err and err.count("error:") == 1 and "Traceback" not in err
    assert out.read_text() == "old\n" and not (tmp_path / "plan.csv.bak").exists()


def test_candidates_file(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    rng = np.random.default_rng(2)
    model = so101_model()
    q = SimulatedKinematicArm(model, np.zeros(model.n_params)).sample_q(80, rng)
    rows = ["pose," + ",".join(f"{j}_deg" for j in JOINTS) + ",x,y,z"]
    rows += [
        f"{i + 1}," + ",".join(repr(float(v)) for v in np.degrees(r)) + ",0.1,0.2,0.3"
        for i, r in enumerate(q)
    ]
    good = tmp_path / "reachable.csv"
    good.write_text("\n".join(rows) + "\n")
    assert main(_plan(tmp_path, "--poses", "20", "--candidates-file", str(good))) == 0
    assert "20 poses (I-optimal of 80 candidates)" in capsys.readouterr().out
    planned = parse_joint_table((tmp_path / "plan.csv").read_text(), JOINTS)
    # every planned pose is one of the given ones
    assert all(np.min(np.abs(q - p).max(axis=1)) < 1e-12 for p in planned)
    out = tmp_path / "p2.csv"
    bad = tmp_path / "bad.csv"
    lines = rows[:6]
    lines[3] = "3," + ",".join(["0", "0", "170", "0", "0"]) + ",0,0,0"  # elbow_flex 170° is beyond its limit
    bad.write_text("\n".join(lines) + "\n")
    assert main(_plan(tmp_path, "--poses", "2", "--candidates-file", str(bad), out=out)) == 2
    err = capsys.readouterr().err
    assert f"{bad}: pose 3" in err and "elbow_flex" in err and not out.exists()
    lines[3] = "3,0,0,nan,0,0,0,0,0"
    bad.write_text("\n".join(lines) + "\n")
    assert main(_plan(tmp_path, "--poses", "2", "--candidates-file", str(bad), out=out)) == 2
    assert "line 4: column 'elbow_flex_deg' is 'nan'" in capsys.readouterr().err and not out.exists()


def test_joint_table_reader() -> None:
    q = parse_joint_table(
        "# a plan\nwrist_roll,pose,shoulder_pan\n0.5,1,0.25\n\n1.5,2,-0.5\n", ("shoulder_pan", "wrist_roll")
    )
    np.testing.assert_array_equal(q, [[0.25, 0.5], [-0.5, 1.5]])
    with pytest.raises(FileFormatError, match="missing joint columns wrist_roll"):
        parse_joint_table("shoulder_pan\n0\n", ("shoulder_pan", "wrist_roll"))
    with pytest.raises(FileFormatError, match="unknown columns wrist_rol"):
        parse_joint_table("shoulder_pan,wrist_roll,wrist_rol\n0,0,0\n", ("shoulder_pan", "wrist_roll"))
    with pytest.raises(FileFormatError, match="has a header but no poses"):
        parse_joint_table("shoulder_pan\n", ("shoulder_pan",))
    with pytest.raises(FileFormatError, match="line 2: 1 fields, the header has 2"):
        parse_joint_table("shoulder_pan,wrist_roll\n0\n", ("shoulder_pan", "wrist_roll"))


@pytest.mark.slow
def test_reach_point_lands_on_the_target_inside_the_limits() -> None:
    from robocal.core.pose_plan import reach_point

    model = so101_model()
    lo, up = model.chain.limits()
    starts = np.random.default_rng(1).uniform(lo, up, (200, 5))
    target = np.array([0.2, 0.0, 0.05])
    q = reach_point(model, target, starts, (lo, up))
    assert q.shape[0] > 20  # most starts get there
    assert np.abs(model.points(q) - target).max() < 1e-9
    model.chain.check_q(q)
    assert reach_point(model, np.array([2.0, 0.0, 0.0]), starts, (lo, up)).shape == (0, 5)  # out of reach


@pytest.mark.slow
@pytest.mark.parametrize("kind", ["touch", "gauge"])
def test_contact_plans_touch_the_given_points(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], kind: str
) -> None:
    from robocal.core.kinematic_errors import ErrorModel
    from robocal.formats.urdf import read_urdf
    from robocal.formats.urdf_chain import chain_from_urdf

    points = [[0.2, -0.025, 0.05], [0.2, 0.025, 0.05]] + ([[0.15, 0.0, 0.09]] if kind == "touch" else [])
    arg = ";".join(",".join(map(str, p)) for p in points)
    extra = ("--kind", kind, "--touch-points", arg, "--poses", "24", "--candidates", "300")
    assert main(_plan(tmp_path, *extra)) == 0
    out = capsys.readouterr().out
    assert "24 poses (I-optimal of" in out and "touch the point it names" in out
    text = (tmp_path / "plan.csv").read_text().splitlines()
    column = "socket" if kind == "gauge" else "group"
    assert text[0] == "pose," + ",".join(JOINTS) + "," + column
    labels = [line.rsplit(",", 1)[1] for line in text[1:]]
    names = ["A", "B"] if kind == "gauge" else ["P1", "P2", "P3"]
    assert set(labels) <= set(names) and len(labels) == 24
    q = parse_joint_table("\n".join(text), JOINTS)
    chain = chain_from_urdf(read_urdf(shipped_urdf("so101")), tip_link="gripper_link")
    chain.check_q(q)
    T = np.eye(4)
    T[:3, 3] = [float(v) for v in TOOL.split(",")]
    tip = ErrorModel(chain, T_tip_tool=T).points(q)
    target = np.array([points[names.index(label)] for label in labels])
    assert np.abs(tip - target).max() < 1e-9  # every planned pose puts the nominal tool on its point


@pytest.mark.parametrize(
    ("extra", "message"),
    [
        (("--kind", "touch"), "--kind touch needs --touch-points with one or more points"),
        (("--kind", "gauge", "--touch-points", "0.2,0,0.05"), "--kind gauge needs --touch-points with two points"),
        (("--touch-points", "0.2,0,0.05"), "--touch-points applies to --kind touch or gauge"),
        (("--kind", "touch", "--touch-points", "0.2,0,0.05", "--criterion", "d"), "apply to --kind points"),
        (("--kind", "touch", "--touch-points", "0.2,0,nan"), "--touch-points '0.2,0,nan': expected three finite"),
        (
            ("--kind", "touch", "--touch-points", "0.2,0,0.05;2,0,0", "--candidates", "100"),
            "--touch-points: point 2 [2.0, 0.0, 0.0] m is reached by 0 configurations",
        ),
    ],
)
def test_bad_contact_plans_write_nothing(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], extra: tuple[str, ...], message: str
) -> None:
    assert main(_plan(tmp_path, *extra)) == 2
    err = capsys.readouterr().err
    assert message in err and err.count("error:") == 1
    assert not (tmp_path / "plan.csv").exists()
