"""A separate validation session: ``kinematics simulate --validation-poses`` and ``identify --validate-data``.

Every pose of ``--data`` is then fitted (a planned set stays the set that was planned) and the held-out poses come
from their own file; touch groups are matched by their label.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from robocal.cli.main import main
from robocal.core.kinematic_problem import Measurements
from robocal.errors import UsageError
from robocal.formats.kinematic_data import parse_measurements
from robocal.workflows.demo.identify import simulate_and_identify
from robocal.workflows.kinematics import job as wf

from .conftest import JOINTS, identify_cli, simulate

TOOL = "0.0121,0,-0.0981"


@pytest.fixture(scope="module")
def session(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """SO-101, 50 planned poses and 17 random held-out poses, seed 2."""
    folder = tmp_path_factory.mktemp("val")
    assert simulate(folder, "--poses", "50", "--seed", "2", "--validation-poses", "17") == 0
    return folder


@pytest.mark.slow
def test_simulate_writes_the_held_out_session_without_changing_the_session(tmp_path: Path, capsys) -> None:
    assert simulate(tmp_path / "a", "--poses", "20", "--seed", "4", "--validation-poses", "9") == 0
    out = capsys.readouterr().out
    assert f"{tmp_path / 'a' / 'points_validation.csv'} (9 held-out poses)" in out
    assert f"--validate-data {tmp_path / 'a' / 'points_validation.csv'}" in out
    assert simulate(tmp_path / "b", "--poses", "20", "--seed", "4") == 0
    # the held-out poses are drawn after the session: the session and the truth are the same without them
    for name in ("points.csv", "truth.json"):
        assert (tmp_path / "a" / name).read_bytes() == (tmp_path / "b" / name).read_bytes()
    assert not (tmp_path / "b" / "points_validation.csv").exists()
    held, _ = parse_measurements((tmp_path / "a" / "points_validation.csv").read_text(), "points", JOINTS)
    assert held.n_poses == 9 and held.p_world_m is not None


@pytest.mark.slow
def test_identify_fits_every_pose_and_validates_on_the_separate_session(
    session: Path, tmp_path: Path, capsys
) -> None:
    assert identify_cli(
        session, session / "points.csv", tmp_path, "--validate-data", str(session / "points_validation.csv")
    ) in (0, 1)
    out = capsys.readouterr().out
    rep = json.loads((tmp_path / "report.json").read_text())
    assert rep["poses"] == {"fit": 50, "validation": 17}
    assert rep["validation_data"] == str(session / "points_validation.csv")
    # the fit's own estimate of the marker noise (0.5 mm per axis simulated)
    noise = rep["errors_mm"]["noise_per_axis"]
    assert 0.4 < noise < 0.65
    assert "validation poses (17): nominal mean" in out
    assert f"the marker noise, {noise:.2f} mm per axis as the fit estimates it" in out
    # the validation errors are the corrected model's against the held-out file's own points
    result = wf.identify(wf.IdentifyRequest(
        session / "so101.urdf", session / "points.csv", tip_link="gripper_link", tool_xyz_m=(0.0121, 0, -0.0981),
        validate_data=session / "points_validation.csv",
    ))  # fmt: skip
    held, _ = parse_measurements((session / "points_validation.csv").read_text(), "points", JOINTS)
    assert held.p_world_m is not None
    expected = np.linalg.norm(
        result.fit.problem.model.points(held.q_rad, result.fit.x) - held.p_world_m, axis=1
    )
    np.testing.assert_allclose(result.validation_errors_m, expected, rtol=0, atol=1e-15)
    assert rep["errors_mm"]["validation"]["corrected"]["mean"] == pytest.approx(
        expected.mean() * 1e3, abs=1e-9
    )


@pytest.mark.slow
def test_the_demo_pipeline_against_the_hidden_truth() -> None:
    """50 planned poses fitted, 17 random held-out poses against the truth (the demo's draw, seed 0).

    Measured over seeds 0-19 (docs/kinematic_identification.md): SO-101 average 0.382 / 0.663 mm, Koch 0.297 /
    0.569; seed 0: SO-101 0.351 / 0.670, Koch 0.253 / 0.502.
    """
    import tempfile

    for robot, mean_mm, max_mm in (("so101", 0.351, 0.670), ("koch", 0.253, 0.502)):
        with tempfile.TemporaryDirectory() as folder:
            sim, result, err = simulate_and_identify(robot, folder)
            model = result.fit.problem.model
            assert result.validation.n_poses == 17 and err.shape == (17,)
            assert result.fit.train_errors_m.size == 50
            assert err.mean() * 1e3 == pytest.approx(mean_mm, abs=0.01)
            assert err.max() * 1e3 == pytest.approx(max_mm, abs=0.02)
            assert err.mean() <= 0.4e-3 and err.max() <= 0.9e-3
            # the covariance's prediction against the parameters' true error at new poses (measured: SO-101 0.305
            # predicted / 0.313 true RMS, Koch 0.299 / 0.271)
            q = sim.arm.read(sim.arm.sample_q(2000, np.random.default_rng(7)))
            true_rms = np.sqrt(
                np.mean(
                    np.sum((model.points(q, result.fit.x) - model.points(q, sim.arm.x_true)) ** 2, axis=1)
                )
            )
            predicted = result.report["errors_mm"]["predicted_rms"] * 1e-3
            assert 0.2e-3 < predicted < 0.4e-3 and 0.8 < predicted / true_rms < 1.25


@pytest.mark.slow
def test_touch_groups_are_matched_by_label(tmp_path: Path, capsys) -> None:
    assert simulate(tmp_path, "--kind", "touch", "--poses", "12", "--validation-poses", "4") == 0
    capsys.readouterr()
    held = tmp_path / "touch_validation.csv"
    lines = held.read_text().splitlines()
    # the same held-out contacts in another order: P3's first, so the file numbers its groups differently
    p3 = [ln for ln in lines[1:] if ln.endswith(",P3")]
    rest = [ln for ln in lines[1:] if not ln.endswith(",P3")]
    (tmp_path / "shuffled.csv").write_text("\n".join([lines[0], *p3, *rest]) + "\n")
    kwargs = {"kind": "touch", "tip_link": "gripper_link", "tool_xyz_m": (0.0121, 0, -0.0981)}
    straight = wf.identify(wf.IdentifyRequest(tmp_path / "so101.urdf", tmp_path / "touch.csv", validate_data=held, **kwargs))
    shuffled = wf.identify(
        wf.IdentifyRequest(tmp_path / "so101.urdf", tmp_path / "touch.csv", validate_data=tmp_path / "shuffled.csv", **kwargs)
    )
    assert straight.validation.n_poses == 12 and straight.fit.train_errors_m.size == 36
    assert (
        straight.validation_errors_m.max() < 0.5e-3
    )  # joint quantisation only: touch data has no marker noise
    np.testing.assert_allclose(
        np.sort(shuffled.validation_errors_m), np.sort(straight.validation_errors_m), atol=1e-15
    )
    (tmp_path / "other.csv").write_text("\n".join([lines[0], lines[1].rsplit(",", 1)[0] + ",P9"]) + "\n")
    with pytest.raises(UsageError, match=r"other.csv: touches point\(s\) P9 that the fitted session never touched "
                       r"\(it touched P1, P2, P3\)"):  # fmt: skip
        wf.identify(
            wf.IdentifyRequest(tmp_path / "so101.urdf", tmp_path / "touch.csv", validate_data=tmp_path / "other.csv", **kwargs)
        )


@pytest.mark.parametrize(
    ("extra", "message"),
    [
        (("--validate-fraction", "0.2"), "error: give --validate-fraction or --validate-data, not both"),
        (
            ("--seed", "3"),
            "error: --seed seeds the random held-out share; with --validate-data nothing is drawn",
        ),
        ((), "missing.csv: no such file"),
    ],
)
def test_refused_validation_options_write_nothing(
    session: Path, tmp_path: Path, capsys, extra, message
) -> None:
    (tmp_path / "id.urdf").write_text("old")
    missing = tmp_path / "missing.csv"
    val = str(session / "points_validation.csv") if extra else str(missing)
    assert identify_cli(session, session / "points.csv", tmp_path, "--validate-data", val, *extra) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith("error: ") and message in err
    assert (tmp_path / "id.urdf").read_text() == "old" and not (tmp_path / "report.json").exists()


def test_a_held_out_pose_outside_the_limits_names_the_file(session: Path, tmp_path: Path, capsys) -> None:
    lines = (session / "points_validation.csv").read_text().splitlines()
    cells = lines[3].split(",")
    cells[1 + JOINTS.index("elbow_flex")] = "2.5"
    bad = tmp_path / "bad_val.csv"
    bad.write_text("\n".join([*lines[:3], ",".join(cells), *lines[4:]]) + "\n")
    assert identify_cli(session, session / "points.csv", tmp_path, "--validate-data", str(bad)) == 2
    err = capsys.readouterr().err
    assert err.startswith(f"error: {bad}: pose 3: joint elbow_flex = 2.5 is outside its limits")
    assert not (tmp_path / "id.urdf").exists() and not (tmp_path / "report.json").exists()


def test_images_and_tag_simulations_refuse_a_validation_session(
    session: Path, tmp_path: Path, capsys
) -> None:
    args = ["--kind", "tag", "--camera", "c.yaml", "--target", "apriltag:tag36h11:0:60"]
    assert (
        identify_cli(
            session,
            session / "points.csv",
            tmp_path,
            "--validate-data",
            str(session / "points_validation.csv"),
            *args,
        )
        == 2
    )
    assert capsys.readouterr().err == (
        "error: --validate-data applies to points, touch and gauge sessions; images use --validate-fraction\n"
    )
    assert simulate(tmp_path / "t", "--kind", "tag", "--validation-poses", "5") == 2
    assert "--validation-poses applies to points, touch and gauge" in capsys.readouterr().err
    assert simulate(tmp_path / "n", "--validation-poses", "-1") == 2
    assert capsys.readouterr().err == "error: --validation-poses must be 0 or more, got -1\n"
    assert not (tmp_path / "t").exists() and not (tmp_path / "n").exists()


@pytest.fixture(scope="module")
def gauge_session(tmp_path_factory: pytest.TempPathFactory) -> Path:
    folder = tmp_path_factory.mktemp("gauge")
    assert simulate(folder, "--kind", "gauge", "--poses", "10", "--validation-poses", "3") == 0
    return folder


@pytest.mark.slow
@pytest.mark.parametrize(
    ("extra", "fit", "held"),
    [
        (("--validate-fraction", "0"), 20, 0),  # nothing held out (was: "need poses in both sockets")
        (("--validate-fraction", "0.05"), 19, 1),  # one pose held out, so one socket only (was refused too)
        (("--validate-data", "a_only"), 20, 3),  # a held-out session in socket A alone
        (("--validate-data", "gauge_validation.csv"), 20, 6),
    ],
)
def test_gauge_validation_may_use_one_socket(
    gauge_session: Path, tmp_path: Path, extra, fit: int, held: int
) -> None:
    if extra[1] == "a_only":
        lines = (gauge_session / "gauge_validation.csv").read_text().splitlines()
        (tmp_path / "a.csv").write_text("\n".join(ln for ln in lines if not ln.endswith(",B")) + "\n")
        extra = ("--validate-data", str(tmp_path / "a.csv"))
    elif extra[0] == "--validate-data":
        extra = ("--validate-data", str(gauge_session / extra[1]))
    args = ["--kind", "gauge", "--gauge-mm", "50", *extra]
    assert identify_cli(gauge_session, gauge_session / "gauge.csv", tmp_path, *args) in (0, 1)
    rep = json.loads((tmp_path / "report.json").read_text())
    assert rep["poses"] == {"fit": fit, "validation": held}
    if held:
        assert rep["errors_mm"]["validation"]["corrected"]["max"] < 0.5  # joint quantisation only


def test_a_gauge_fit_still_needs_both_sockets(gauge_session: Path, tmp_path: Path, capsys) -> None:
    lines = (gauge_session / "gauge.csv").read_text().splitlines()
    (tmp_path / "a.csv").write_text("\n".join(ln for ln in lines if not ln.endswith(",B")) + "\n")
    args = ["--kind", "gauge", "--gauge-mm", "50"]
    assert identify_cli(gauge_session, tmp_path / "a.csv", tmp_path, *args) == 2
    assert "a gauge session needs poses in both socket A and socket B" in capsys.readouterr().err
    with pytest.raises(UsageError, match=r"gauge sockets are 0 \(A\) and 1 \(B\), got \[0, 2\]"):
        Measurements("gauge", np.zeros((2, 5)), group=np.array([0, 2]), distance_m=0.05)


def _plan(out: Path, *extra: str) -> int:
    from .conftest import SO101_URDF

    args = ["kinematics", "plan", "--urdf", str(SO101_URDF), "--tip-link", "gripper_link", "--tool-xyz", TOOL]
    return main([*args, "--out", str(out), *extra])


@pytest.mark.slow
def test_plan_writes_held_out_poses_beside_the_plan_without_changing_it(tmp_path: Path, capsys) -> None:
    assert _plan(tmp_path / "a.csv", "--poses", "30", "--validation-poses", "12") == 0
    out = capsys.readouterr().out
    assert f"wrote {tmp_path / 'a_validation.csv'} (12 random held-out poses)" in out
    assert _plan(tmp_path / "b.csv", "--poses", "30") == 0
    assert (tmp_path / "a.csv").read_bytes() == (tmp_path / "b.csv").read_bytes()
    assert not (tmp_path / "b_validation.csv").exists()
    from robocal.formats.kinematic_data import parse_joint_table

    planned = parse_joint_table((tmp_path / "a.csv").read_text(), JOINTS)
    held = parse_joint_table((tmp_path / "a_validation.csv").read_text(), JOINTS)
    assert held.shape == (12, 5)
    # none of them is a planned pose, all inside the limits minus the planning margin
    assert min(np.abs(planned - h).max(axis=1).min() for h in held) > 1e-6
    from .conftest import so101_model

    lo, up = so101_model().chain.limits()
    assert np.all(held >= lo + 0.05 - 1e-12) and np.all(held <= up - 0.05 + 1e-12)


@pytest.mark.slow
def test_plan_touch_held_out_poses_name_their_point(tmp_path: Path, capsys) -> None:
    points = "0.2,0,0.05;0.2,0.06,0.05"
    args = ["--kind", "touch", "--touch-points", points, "--poses", "12", "--candidates", "50"]
    assert _plan(tmp_path / "t.csv", *args, "--validation-poses", "4") == 0
    capsys.readouterr()
    lines = (tmp_path / "t_validation.csv").read_text().splitlines()
    assert lines[0].endswith(",group") and len(lines) == 5
    assert {ln.rsplit(",", 1)[1] for ln in lines[1:]} <= {"P1", "P2"}


@pytest.mark.slow
@pytest.mark.parametrize(
    ("extra", "message"),
    [
        (
            ("--validation-poses", "1990"),
            "--validation-poses 1990: only 1950 candidate poses are left beside the plan",
        ),
        (("--validation-poses", "-2"), "--validation-poses must be 0 or more, got -2"),
        (
            ("--kind", "tag", "--validation-poses", "3"),
            "--validation-poses applies to points, touch and gauge",
        ),
    ],
)
def test_plan_refuses_bad_held_out_counts_and_writes_nothing(tmp_path: Path, capsys, extra, message) -> None:
    assert _plan(tmp_path / "x.csv", *extra) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith("error: ") and message in err
    assert list(tmp_path.iterdir()) == []
