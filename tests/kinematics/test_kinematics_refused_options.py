"""Options of identify, plan and simulate a user can get wrong: each one error line, exit 2, nothing written."""

from __future__ import annotations

from pathlib import Path

import pytest

from robocal.cli.main import main

from .conftest import points_session, simulate  # noqa: F401  (points_session is a fixture)

TOOL = ("--tip-link", "gripper_link", "--tool-xyz", "0.0121,0,-0.0981")


def _identify(session: Path, tmp: Path, *extra: str) -> list[str]:
    return [
        "kinematics", "identify", "--urdf", str(session / "so101.urdf"), "--data", str(session / "points.csv"),
        *TOOL, "--out", str(tmp / "id.urdf"), "--report", str(tmp / "r.json"), *extra,
    ]  # fmt: skip


def _one_error(capsys: pytest.CaptureFixture[str], message: str) -> None:
    err = capsys.readouterr().err
    assert err.count("error:") == 1 and message in err and "Traceback" not in err, err


@pytest.mark.slow
@pytest.mark.parametrize(
    ("extra", "message"),
    [
        (("--seed", "-1"), "error: --seed must be a non-negative integer, got -1"),
        (("--gauge-mm", "50"), "error: --gauge-mm applies to --kind gauge"),
        (("--ur-hash", "calib_1"), "error: --ur-hash applies to --ur-yaml"),
    ],
)
def test_identify_refuses_options_it_would_ignore_or_crash_on(
    points_session: Path,  # noqa: F811
    tmp_path: Path,
    capsys: pytest.CaptureFixture[str],
    extra: tuple[str, ...],
    message: str,
) -> None:
    (tmp_path / "id.urdf").write_text("old\n")
    assert main(_identify(points_session, tmp_path, *extra)) == 2
    _one_error(capsys, message)
    assert (tmp_path / "id.urdf").read_text() == "old\n"
    assert not (tmp_path / "id.urdf.bak").exists() and not (tmp_path / "r.json").exists()


def test_plan_refuses_a_negative_seed(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    from robocal.workflows.kinematics.sim import shipped_urdf

    code = main(
        ["kinematics", "plan", "--urdf", str(shipped_urdf("so101")), *TOOL, "--out", str(tmp_path / "p.csv"),
         "--poses", "20", "--candidates", "100", "--seed", "-3"]
    )  # fmt: skip
    assert code == 2
    _one_error(capsys, "error: --seed must be a non-negative integer, got -3")
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize(
    ("options", "message"),
    [
        (("--seed", "-1"), "error: --seed must be a non-negative integer, got -1"),
        (("--robot", "ur5"), "error: unknown simulated robot 'ur5'; valid: so101, koch"),
        (("--kind", "gauge", "--gauge-mm", "0"), "error: --gauge-mm must be a positive number, got 0.0"),
        (("--kind", "tag", "--seed", "-2"), "error: --seed must be a non-negative integer, got -2"),
        (("--kind", "tag", "--robot", "koch", "--camera-on-tool"), "simulated for so101 only"),
    ],
)
def test_a_failed_simulation_makes_no_folder(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], options: tuple[str, ...], message: str
) -> None:
    assert simulate(tmp_path / "sim", *options) == 2
    _one_error(capsys, message)
    assert list(tmp_path.iterdir()) == []  # `--out sim` is made only when the files are written


@pytest.mark.parametrize(
    ("options", "message"),
    [
        (("--kind", "foo"), "error: --kind 'foo'; valid: points, touch, gauge, tag"),
        (("--kind", "gauge", "--gauge-mm", "nan"), "error: --gauge-mm must be a positive number, got nan"),
        (("--gauge-mm", "-50"), "error: --gauge-mm must be a positive number, got -50.0"),
    ],
)
def test_simulate_names_the_bad_option(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], options: tuple[str, ...], message: str
) -> None:
    assert simulate(tmp_path / "sim", *options) == 2
    _one_error(capsys, message)
    assert list(tmp_path.iterdir()) == []
