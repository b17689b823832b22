"""``robocal ur defaults/verify/plot/correct --urdf-in`` and ``demo --robot ur10e`` via the CLI entry point."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import pytest
from tests.net import free_port

import robocal.workflows.ur.job as wf
from robocal.cli.main import main
from robocal.core.dh import DHParameters
from robocal.core.ur import check_rpy_convention, correct_kinematics, default_kinematics, nominal_dh
from robocal.errors import UsageError
from robocal.formats.ur_kinematics import (
    kinematics_to_text,
    read_kinematics,
    write_kinematics,
)

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


@pytest.mark.slow
def test_plot_writes_png(tmp_path: Path, dh_sets: dict[int, DHParameters]) -> None:
    dh = _write_dh(tmp_path / "dh.yaml", dh_sets[3])
    fig = tmp_path / "fig.png"
    assert main(["ur", "plot", "--dh", str(dh), "--out", str(fig)]) == 0
    assert fig.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_run_demo_writes_verified_file(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["demo", "--robot", "ur10e", "--out", str(tmp_path)]) == 0
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


def _one_error_line(err: str) -> str:
    lines = err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: "), lines
    return lines[0]


def test_verify_host_validates_port_and_counts(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    f = tmp_path / "k.yaml"
    write_kinematics(f, default_kinematics("ur5e", "urdf"))
    assert main(["ur", "verify", str(f), "--host", "127.0.0.1", "--port", "70000", "--timeout", "0.5"]) == 2
    assert "--port 70000: expected 1..65535" in _one_error_line(capsys.readouterr().err)
    port = str(free_port())
    assert (
        main(["ur", "verify", str(f), "--host", "127.0.0.1", "--port", port, "--controller-samples", "0"])
        == 2
    )
    assert "--controller-samples 0: expected at least 1" in _one_error_line(capsys.readouterr().err)


def test_failed_extract_leaves_existing_file_alone_one_error_line(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "k.yaml"
    out.write_text("keep me\n")
    port = str(free_port())
    assert (
        main(["ur", "extract", "--host", "127.0.0.1", "--port", port, "--out", str(out), "--timeout", "0.5"])
        == 3
    )
    assert "cannot connect" in _one_error_line(capsys.readouterr().err)
    assert out.read_text() == "keep me\n"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["k.yaml"]
    assert main(["ur", "defaults", "--model", "ur99", "--out", str(out)]) == 2
    assert "unknown UR model 'ur99'" in _one_error_line(capsys.readouterr().err)


def test_overwrite_note_after_success(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "k.yaml"
    out.write_text("old\n")
    assert main(["ur", "defaults", "--model", "ur5e", "--out", str(out)]) == 0
    assert "previous file kept as k.yaml.bak" in capsys.readouterr().err
    assert (tmp_path / "k.yaml.bak").read_text() == "old\n"


def test_urdf_out_must_differ_from_out(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    urdf = tmp_path / "ur.urdf"
    urdf.write_text(ur_urdf_text(default_kinematics("ur5e", "urdf")))
    out = tmp_path / "k.yaml"
    code = main(
        [
            "ur",
            "correct",
            "--model",
            "ur5e",
            "--out",
            str(out),
            "--urdf-in",
            str(urdf),
            "--urdf-out",
            str(tmp_path / "." / "k.yaml"),
        ]
    )
    assert code == 2
    assert "--urdf-out" in _one_error_line(capsys.readouterr().err)
    assert not out.exists()


def test_plot_unknown_format_exit_2_nothing_written(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    fig = tmp_path / "fig.xyz"
    assert main(["ur", "plot", "--model", "ur10e", "--out", str(fig)]) == 2
    assert "fig.xyz: unsupported figure format 'xyz'" in _one_error_line(capsys.readouterr().err)
    assert list(tmp_path.iterdir()) == []


def _urdf_pair_setup(tmp_path: Path, existing: bool) -> tuple[Path, Path, Path, dict[Path, bytes | None]]:
    urdf_in = tmp_path / "ur.urdf"
    urdf_in.write_text(ur_urdf_text(default_kinematics("ur10e", "urdf")))
    urdf_out = tmp_path / "ur_cal.urdf"
    out = tmp_path / "cal.yaml"
    if existing:
        urdf_out.write_text("old urdf\n")
        (tmp_path / "ur_cal.urdf.bak").write_text("older urdf\n")
        out.write_text("old yaml\n")
    before = {
        p: (p.read_bytes() if p.exists() else None)
        for p in (urdf_out, tmp_path / "ur_cal.urdf.bak", out, tmp_path / "cal.yaml.bak")
    }
    return urdf_in, urdf_out, out, before


def _correct_pair_args(out: Path, urdf_in: Path, urdf_out: Path, *extra: str) -> list[str]:
    """``ur correct --model ur10e [extra] --out OUT --urdf-in IN --urdf-out OUT_URDF``."""
    return ["ur", "correct", "--model", "ur10e", *extra, "--out", str(out), "--urdf-in", str(urdf_in),
            "--urdf-out", str(urdf_out)]  # fmt: skip


@pytest.mark.parametrize(
    ("given", "expected"), [("URDF", "urdf"), ("Upstream", "upstream"), (" upstream ", "upstream")]
)
def test_rpy_any_case(tmp_path: Path, given: str, expected: str) -> None:
    assert check_rpy_convention(given) == expected
    a, b = tmp_path / "a.yaml", tmp_path / "b.yaml"
    assert main(["ur", "correct", "--model", "ur10e", "--rpy", given, "--out", str(a)]) == 0
    assert main(["ur", "correct", "--model", "ur10e", "--rpy", expected, "--out", str(b)]) == 0
    assert a.read_text() == b.read_text()
    assert a.read_text().splitlines()[0].endswith(f"rpy convention: {expected}")
    assert main(["ur", "defaults", "--model", "UR5E", "--rpy", given, "--out", str(a)]) == 0
    assert a.read_text() == kinematics_to_text(default_kinematics("ur5e", expected))


def test_rpy_unknown_is_refused(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "a.yaml"
    assert main(["ur", "defaults", "--model", "ur5e", "--rpy", "eigen", "--out", str(out)]) == 2
    assert "--rpy 'eigen': expected one of urdf, upstream" in _one_error_line(capsys.readouterr().err)
    assert not out.exists()


def test_defaults_help_says_upstream_by_default_and_urdf_is_accepted(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    assert main(["ur", "defaults", "--help"]) == 0
    text = " ".join(capsys.readouterr().out.split())
    assert "upstream mode" in text and "checked-in default files" in text
    assert "--rpy urdf writes URDF-convention angles" in text
    out = tmp_path / "d.yaml"
    assert main(["ur", "defaults", "--model", "ur5e", "--out", str(out)]) == 0
    assert "rpy convention: upstream" in out.read_text().splitlines()[0]
    assert "yaw: 3.141592653589793" in out.read_text()  # upstream's (π/2, π, π) wrist_3
    assert main(["ur", "defaults", "--model", "ur5e", "--rpy", "urdf", "--out", str(out)]) == 0
    assert out.read_text() == kinematics_to_text(default_kinematics("ur5e", "urdf"))


@pytest.mark.parametrize("existing", [False, True], ids=["new_files", "existing_files"])
def test_yaml_write_failure_restores_the_urdf(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch, existing: bool
) -> None:
    urdf_in, urdf_out, out, before = _urdf_pair_setup(tmp_path, existing)
    calls: list[Path] = []

    def failing_yaml(path: Any, text: str, **kw: Any) -> Path:
        calls.append(Path(path))
        raise UsageError(f"cannot write {path}: No space left on device")

    monkeypatch.setattr(wf, "atomic_write_text", failing_yaml)
    args = _correct_pair_args(out, urdf_in, urdf_out)
    assert main(args) == 2
    assert "No space left on device" in _one_error_line(capsys.readouterr().err)
    assert calls == [out]  # the YAML was attempted after the URDF had been written
    after = {p: (p.read_bytes() if p.exists() else None) for p in before}
    assert after == before
    assert sorted(p.name for p in tmp_path.iterdir() if p.name.startswith(".")) == []  # no temp files left


def test_urdf_write_failure_writes_no_yaml(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    urdf_in, urdf_out, out, before = _urdf_pair_setup(tmp_path, existing=True)

    def failing_bytes(path: Any, data: bytes, **kw: Any) -> Path:
        raise UsageError(f"cannot write {path}: Read-only file system")

    monkeypatch.setattr(wf, "atomic_write_bytes", failing_bytes)
    args = _correct_pair_args(out, urdf_in, urdf_out)
    assert main(args) == 2
    assert f"cannot write {urdf_out}: Read-only file system" in _one_error_line(capsys.readouterr().err)
    assert {p: (p.read_bytes() if p.exists() else None) for p in before} == before


def test_urdf_pair_success_writes_both(tmp_path: Path) -> None:
    urdf_in, urdf_out, out, _ = _urdf_pair_setup(tmp_path, existing=True)
    args = _correct_pair_args(out, urdf_in, urdf_out, "--rpy", "UPSTREAM")
    assert main(args) == 0
    assert out.read_text() == kinematics_to_text(correct_kinematics(nominal_dh("ur10e"), "upstream"))
    assert (tmp_path / "cal.yaml.bak").read_text() == "old yaml\n"
    assert (tmp_path / "ur_cal.urdf.bak").read_text() == "old urdf\n"
    assert "shoulder_pan_joint" in urdf_out.read_text()
