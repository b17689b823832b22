"""``robocal ur defaults/verify/plot/correct --urdf-in`` and ``run_demo`` via the CLI entry point."""

from __future__ import annotations

from pathlib import Path

import pytest

from robocal.cli.main import main
from robocal.cli.ur import run_demo
from robocal.core.dh import DHParameters
from robocal.core.ur import correct_kinematics, default_kinematics
from robocal.formats.ur_kinematics import read_kinematics

from .test_ur_urdf import ur_urdf_text


def _write_dh(path: Path, dh: DHParameters) -> Path:
    path.write_text(
        f"dh_theta: {list(dh.theta_rad)}\ndh_a: {list(dh.a_m)}\n"
        f"dh_d: {list(dh.d_m)}\ndh_alpha: {list(dh.alpha_rad)}\n"
    )
    return path


def test_defaults_regenerates_ur5e(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "default_kinematics.yaml"
    assert main(["ur", "defaults", "--model", "ur5e", "--out", str(out)]) == 0
    text = out.read_text()
    assert "    z: -2.0448811822978515e-11\n" in text
    assert "  wrist_3:\n    x: 0.0\n    y: 0.0996\n" in text
    assert "    roll: 1.570796326589793\n    pitch: 3.141592653589793\n    yaw: 3.141592653589793\n" in text
    assert text.endswith("  hash: calib_12788084448423163542\n")
    assert read_kinematics(out) == default_kinematics("ur5e", "upstream")
    assert "wrote" in capsys.readouterr().out


def test_verify_urdf_mode_ok_upstream_mode_warns(
    tmp_path: Path, dh_sets: dict[int, DHParameters], capsys: pytest.CaptureFixture[str]
) -> None:
    dh = _write_dh(tmp_path / "dh.yaml", dh_sets[1])
    good, upstream = tmp_path / "good.yaml", tmp_path / "upstream.yaml"
    assert main(["ur", "correct", "--dh", str(dh), "--out", str(good)]) == 0
    assert main(["ur", "correct", "--dh", str(dh), "--out", str(upstream), "--rpy", "upstream"]) == 0
    capsys.readouterr()
    assert main(["ur", "verify", str(good), "--dh", str(dh), "--samples", "200"]) == 0
    assert "match" in capsys.readouterr().out
    assert main(["ur", "verify", str(upstream), "--dh", str(dh), "--samples", "200"]) == 1
    err = capsys.readouterr().err
    assert "warning: kinematics YAML" in err and "FK differs from the DH model by up to" in err


def test_verify_hash_mismatch_and_model_deltas(
    tmp_path: Path, dh_sets: dict[int, DHParameters], capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "k.yaml"
    assert main(["ur", "defaults", "--model", "ur10e", "--out", str(out), "--rpy", "urdf"]) == 0
    assert main(["ur", "verify", str(out), "--model", "ur10e"]) == 0
    deltas = tmp_path / "d.yaml"
    deltas.write_text(
        "delta_theta: [0, 0, 0, 0, 0, 0]\ndelta_a: [0, 0, 0, 0, 0, 0]\n"
        "delta_d: [0, 0, 0, 0, 0, 0.001]\ndelta_alpha: [0, 0, 0, 0, 0, 0]\n"
    )
    capsys.readouterr()
    assert main(["ur", "verify", str(out), "--model", "ur10e", "--deltas", str(deltas)]) == 1
    err = capsys.readouterr().err
    assert "does not match the DH" in err
    assert "FK differs from the DH model by up to 0.001 m" in err


def test_correct_updates_urdf_and_verify_urdf(
    tmp_path: Path, dh_sets: dict[int, DHParameters], capsys: pytest.CaptureFixture[str]
) -> None:
    dh = _write_dh(tmp_path / "dh.yaml", dh_sets[3])
    urdf_in = tmp_path / "ur.urdf"
    urdf_in.write_text(ur_urdf_text(default_kinematics("ur10e", "urdf")))
    urdf_out = tmp_path / "ur_cal.urdf"
    out = tmp_path / "k.yaml"
    code = main(
        [
            "ur",
            "correct",
            "--dh",
            str(dh),
            "--out",
            str(out),
            "--rpy",
            "upstream",
            "--urdf-in",
            str(urdf_in),
            "--urdf-out",
            str(urdf_out),
        ]
    )
    assert code == 0
    # the URDF always gets URDF-convention angles, whatever --rpy the YAML uses
    assert main(["ur", "verify", "--dh", str(dh), "--urdf", str(urdf_out)]) == 0
    assert "<!-- UR arm (test) -->" in urdf_out.read_text()
    assert read_kinematics(out).rpy_convention == "upstream"


def test_urdf_flags_must_come_together_nothing_written(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "k.yaml"
    assert main(["ur", "correct", "--model", "ur5e", "--out", str(out), "--urdf-in", "x.urdf"]) == 2
    assert "--urdf-in and --urdf-out must be given together" in capsys.readouterr().err
    assert not out.exists()


def test_plot_writes_png(tmp_path: Path, dh_sets: dict[int, DHParameters]) -> None:
    dh = _write_dh(tmp_path / "dh.yaml", dh_sets[3])
    fig = tmp_path / "fig.png"
    assert main(["ur", "plot", "--dh", str(dh), "--out", str(fig)]) == 0
    assert fig.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_run_demo_writes_verified_file(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert run_demo("ur10e", tmp_path) == 0
    out = tmp_path / "ur10e_calibration.yaml"
    kin = read_kinematics(out)
    assert kin.hash == "calib_8779175261365510310"
    assert kin == correct_kinematics(kin_dh_set3(), "urdf")
    text = capsys.readouterr().out
    assert "d2 = 439.141 m" in text and "match" in text


def kin_dh_set3() -> DHParameters:
    from .conftest import calibrated_dh

    return calibrated_dh(3)


def test_correct_reports_deviation_from_nominal(
    tmp_path: Path, dh_sets: dict[int, DHParameters], capsys: pytest.CaptureFixture[str]
) -> None:
    dh = _write_dh(tmp_path / "dh.yaml", dh_sets[3])
    assert main(["ur", "correct", "--dh", str(dh), "--out", str(tmp_path / "k.yaml")]) == 0
    assert "deviation from nominal ur10e: 0.879 mm (d6), 6.938 mrad" in capsys.readouterr().out


def test_deviation_from_nominal_values(dh_sets: dict[int, DHParameters]) -> None:
    from robocal.core.ur import deviation_from_nominal

    dev = deviation_from_nominal(correct_kinematics(dh_sets[1], "upstream"))
    assert dev.model == "ur10" and dev.length_field == "a3"
    assert dev.length_m == pytest.approx(0.0011405691720679512, abs=1e-12)
    assert dev.angle_rad == pytest.approx(0.013483227116492602, abs=1e-12)
    nominal = deviation_from_nominal(default_kinematics("ur5e"), "ur5e")
    assert nominal.length_m == 0.0 and nominal.angle_rad < 1e-15


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["--timeout", "0"], "--timeout 0.0: expected a positive number"),
        (["--port", "70000"], "--port 70000"),
    ],
)
def test_extract_bad_timeout_or_port_exit_2(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], args: list[str], message: str
) -> None:
    out = tmp_path / "k.yaml"
    assert main(["ur", "extract", "--host", "127.0.0.1", "--out", str(out), *args]) == 2
    assert message in capsys.readouterr().err
    assert not out.exists()
