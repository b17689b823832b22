"""``kinematics identify`` refuses sessions that cannot support a number (issue 27 item 1).

Each case exited 0 (or 70) and wrote a URDF before the gates: one pose repeated, a few poses repeated, no joint
moving, a joint that never moved, absurd prior options, held-out poses that are the fitted ones.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from robocal.core.kinematic_problem import Measurements, Problem, analyse, free_indices

from .conftest import identify_cli, so101_model


def _rows(session: Path) -> tuple[str, list[str]]:
    lines = (session / "points.csv").read_text().splitlines()
    return lines[0], lines[1:]


def _write(path: Path, header: str, rows: list[str]) -> Path:
    path.write_text("\n".join([header, *rows]) + "\n")
    return path


def _refused(session: Path, data: Path, out: Path, capsys: pytest.CaptureFixture[str], *extra: str) -> str:
    """Run identify on ``data``: exit 2, one ``error:`` line, nothing written; the error line."""
    assert identify_cli(session, data, out, *extra) == 2
    err = capsys.readouterr().err
    assert err.startswith("error: ") and err.count("\n") == 1 and "Traceback" not in err
    assert not (out / "id.urdf").exists() and not (out / "report.json").exists()
    return err


def test_one_row_repeated_is_one_pose(points_session: Path, tmp_path: Path, capsys) -> None:
    header, rows = _rows(points_session)
    data = _write(tmp_path / "one.csv", header, [rows[0]] * 50)
    err = _refused(points_session, data, tmp_path, capsys)
    assert err == (
        f"error: too few poses: {data} has 1 distinct pose (50 rows repeat 1 distinct pose), 3 equations for the "
        "23 parameters this model can identify; record at least 9 different poses (20 or more for a useful result; "
        "robocal kinematics plan chooses them)\n"
    )


def test_three_poses_repeated_are_three_poses(points_session: Path, tmp_path: Path, capsys) -> None:
    header, rows = _rows(points_session)
    data = _write(tmp_path / "three.csv", header, rows[:3] * 17)
    err = _refused(points_session, data, tmp_path, capsys)
    assert f"{data} has 3 distinct poses (51 rows repeat 3 distinct poses), 9 equations for the 23" in err


def test_readings_within_a_tick_are_one_pose(
    points_session: Path, tmp_path: Path, capsys
) -> None:
    header, rows = _rows(points_session)
    cells = rows[0].split(",")
    step = 2 * np.pi / 4096
    near = []
    for k in range(30):  # 30 readings of one pose, each within a third of a tick, each point measured anew
        c = list(cells)
        c[1] = repr(float(cells[1]) + (k % 3 - 1) * step / 3)
        c[6] = repr(float(cells[6]) + 1e-4 * k)
        near.append(",".join(c))
    err = _refused(points_session, _write(tmp_path / "near.csv", header, near), tmp_path, capsys)
    assert "has 1 distinct pose (30 rows repeat 1 distinct pose)" in err
    # with --ticks 0 (exact readings) the same rows are 3 poses, still too few
    err = _refused(points_session, tmp_path / "near.csv", tmp_path, capsys, "--ticks", "0")
    assert "has 3 distinct poses (30 rows repeat 3 distinct poses)" in err


def test_no_joint_moving_is_refused_not_a_crash(points_session: Path, tmp_path: Path, capsys) -> None:
    header, rows = _rows(points_session)
    cells = rows[0].split(",")
    still = []
    for k in range(50):  # the arm never moves; the tracker's reading jitters
        c = list(cells)
        c[0], c[6] = str(k + 1), repr(float(cells[6]) + 1e-4 * float(np.sin(k)))
        still.append(",".join(c))
    err = _refused(points_session, _write(tmp_path / "still.csv", header, still), tmp_path, capsys)
    assert "has 1 distinct pose (50 rows repeat 1 distinct pose)" in err


def test_a_joint_that_never_moved_is_named(points_session: Path, tmp_path: Path, capsys) -> None:
    header, rows = _rows(points_session)
    col = header.split(",").index("wrist_flex")
    held = []
    for row in rows:
        c = row.split(",")
        c[col] = "0.25"
        held.append(",".join(c))
    err = _refused(points_session, _write(tmp_path / "held.csv", header, held), tmp_path, capsys)
    assert err.startswith("error: the poses identify 19 of the 23 parameters this model can identify; ")
    # the joint that did not move comes first, with the parameters it leaves unseen
    unseen = err.split("not identifiable from them: ")[1].split(" (wrist_flex did not move in the poses (always 0.25)")
    assert sorted(unseen[0].split(", ")) == ["wrist_flex.rx", "wrist_flex.ry"]


@pytest.mark.parametrize(
    ("option", "message"),
    [
        (("--prior-deg", "1e300"), "error: --prior-deg must be from 1e-06 to 180, got 1e+300\n"),
        (("--prior-mm", "1e-300"), "error: --prior-mm must be from 1e-06 to 1000, got 1e-300\n"),
        (("--prior-offset-deg", "720"), "error: --prior-offset-deg must be from 1e-06 to 180, got 720\n"),
        (("--ticks", "-1"), "error: --ticks must be 0 (exact readings) or a number of ticks per turn, got -1\n"),
    ],
)
def test_absurd_option_values_are_one_error_line(
    points_session: Path, tmp_path: Path, capsys, option: tuple[str, str], message: str
) -> None:
    assert identify_cli(points_session, points_session / "points.csv", tmp_path, *option) == 2
    assert capsys.readouterr().err == message
    assert not (tmp_path / "id.urdf").exists()


def test_held_out_poses_that_are_the_fitted_ones_are_no_validation(
    points_session: Path, tmp_path: Path, capsys
) -> None:
    data = points_session / "points.csv"
    assert identify_cli(points_session, data, tmp_path, "--validate-data", str(data)) == 1
    captured = capsys.readouterr()
    assert "validation poses" not in captured.out
    assert "warning: 60 held-out poses repeat fitted poses (the same encoder readings): left out" in captured.err
    assert "warning: not validated: no held-out pose differs from the fitted ones" in captured.err
    rep = json.loads((tmp_path / "report.json").read_text())
    assert rep["poses"] == {"fit": 60, "validation": 0}
    assert rep["errors_mm"]["validation"]["corrected"] is None


def test_exact_copies_count_once_and_give_the_session_s_numbers(
    points_session: Path, tmp_path: Path, capsys
) -> None:
    header, rows = _rows(points_session)
    (tmp_path / "a").mkdir()
    (tmp_path / "b").mkdir()
    assert identify_cli(points_session, points_session / "points.csv", tmp_path / "a") in (0, 1)
    capsys.readouterr()
    doubled = _write(tmp_path / "doubled.csv", header, rows + rows[::-1])
    assert identify_cli(points_session, doubled, tmp_path / "b") == 1
    assert "warning: " + f"{doubled}: 60 of 120 rows repeat an earlier row exactly" in capsys.readouterr().err
    a = json.loads((tmp_path / "a" / "report.json").read_text())
    b = json.loads((tmp_path / "b" / "report.json").read_text())
    assert b["poses"] == a["poses"] == {"fit": 45, "validation": 15}
    assert b["parameters"] == a["parameters"] and b["errors_mm"] == a["errors_mm"]


def test_identifiability_of_one_repeated_pose_does_not_crash() -> None:
    # the pivoted QR met a NaN column norm here (ValueError: zero-size array, exit 70)
    model = so101_model()
    q = np.tile([[1.5018, -0.02454, -1.1290, -0.1580, 1.6582]], (50, 1))
    data = Measurements("points", q, np.tile([[0.0534, -0.1549, 0.5107]], (50, 1)))
    ident = analyse(Problem(model, data, free_indices(model, ["base"]), np.zeros(model.n_params)))
    assert ident.rank == 3
    reasons = {u.name: u.reason for u in ident.unidentifiable}
    assert reasons["wrist_flex.offset"] == "wrist_flex did not move in the poses (always -0.158); move it through its range"
    assert reasons["shoulder_pan.x"].startswith("shoulder_pan did not move in the poses (always 1.502)")
