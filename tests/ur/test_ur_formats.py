"""Kinematics YAML writer/reader, DH and deltas inputs, the malformed-input matrix through the CLI."""

from __future__ import annotations

import re
from pathlib import Path

import pytest
from hypothesis import given

from robocal.cli.main import main
from robocal.core.dh import DHParameters
from robocal.core.ur import correct_kinematics, nominal_dh
from robocal.errors import FileFormatError
from robocal.formats.ur_kinematics import (
    kinematics_to_text,
    read_deltas,
    read_dh,
    read_kinematics,
    write_kinematics,
)

from .test_ur_core import make_realistic, realistic


def dh_yaml(dh: DHParameters) -> str:
    return (
        f"dh_theta: {list(dh.theta_rad)}\n"
        f"dh_a: {list(dh.a_m)}\n"
        f"dh_d: {list(dh.d_m)}\n"
        f"dh_alpha: {list(dh.alpha_rad)}\n"
    )


def test_yaml_layout_key_order_hash_last_no_negative_zero(dh_sets: dict[int, DHParameters]) -> None:
    text = kinematics_to_text(correct_kinematics(dh_sets[2]))
    lines = text.splitlines()
    assert lines[1] == "kinematics:"
    assert [ln.strip()[:-1] for ln in lines if ln.startswith("  ") and not ln.startswith("    ")][:6] == [
        "shoulder",
        "upper_arm",
        "forearm",
        "wrist_1",
        "wrist_2",
        "wrist_3",
    ]
    assert lines[2:9] == [
        "  shoulder:",
        "    x: 0.0",
        "    y: 0.0",
        "    z: 0.18055510502488192",
        "    roll: 0.0",
        "    pitch: 0.0",
        "    yaw: 1.5961352531693174e-07",
    ]
    assert lines[-1] == "  hash: calib_12699676364380556618"
    assert not any(ln.endswith((": -0.0", ": -0")) for ln in lines)
    assert '"' not in text and "'" not in text.split("\n", 1)[1]


@given(realistic)
def test_yaml_round_trip_is_bit_exact(params: tuple) -> None:  # type: ignore[type-arg]
    import tempfile

    kin = correct_kinematics(make_realistic(params))
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "k.yaml"
        write_kinematics(path, kin)
        back = read_kinematics(path)
    assert back == kin


def test_write_keeps_backup_and_reads_upstream_convention(tmp_path: Path) -> None:
    out = tmp_path / "k.yaml"
    write_kinematics(out, correct_kinematics(nominal_dh("ur5e"), "urdf"))
    first = out.read_text()
    write_kinematics(out, correct_kinematics(nominal_dh("ur5e"), "upstream"))
    assert (tmp_path / "k.yaml.bak").read_text() == first
    assert read_kinematics(out).rpy_convention == "upstream"


def test_read_dh_and_deltas(tmp_path: Path, dh_sets: dict[int, DHParameters]) -> None:
    p = tmp_path / "dh.yaml"
    p.write_text(dh_yaml(dh_sets[3]))
    assert read_dh(p) == dh_sets[3]
    conf = tmp_path / "calibration.conf"
    conf.write_text(
        "[mounting]\ncalibration_status = 2\n"
        "delta_theta = [ 0.1, 0, 0, 0, 0, 0 ]\ndelta_a = [0, 0.001, 0, 0, 0, 0]\n"
        "delta_d = [0, 0, 0, 0, 0, 0.002]\ndelta_alpha = [0, 0, 0, 0, 0, 0]\n"
    )
    deltas = read_deltas(conf)
    assert deltas.theta_rad[0] == 0.1 and deltas.a_m[1] == 0.001 and deltas.d_m[5] == 0.002
    y = tmp_path / "deltas.yaml"
    y.write_text(
        "delta_theta: [0, 0, 0, 0, 0, 0]\ndelta_a: [0, 0, 0, 0, 0, 0]\n"
        "delta_d: [0, 1.5, -1.5, 0, 0, 0]\ndelta_alpha: [0, 0, 0, 0, 0, 0]\n"
    )
    assert read_deltas(y).d_m == (0.0, 1.5, -1.5, 0.0, 0.0, 0.0)


GOOD = {
    "dh_theta": "[0, 0, 0, 0, 0, 0]",
    "dh_a": "[0, -0.6127, -0.57155, 0, 0, 0]",
    "dh_d": "[0.1807, 1.0, -1.0, 0.17415, 0.11985, 0.11655]",
    "dh_alpha": "[1.570796327, 0.001, 0, 1.570796327, -1.570796327, 0]",
}


def _dh_text(**override: str | None) -> str:
    fields = {**GOOD, **override}
    return "".join(f"{k}: {v}\n" for k, v in fields.items() if v is not None)


MALFORMED = [
    ("missing_key", _dh_text(dh_d=None), r"missing key dh_d"),
    ("wrong_length", _dh_text(dh_a="[0, 1, 2]"), r"dh_a has 3 values \(\[0, 1, 2\]\); expected 6 numbers"),
    ("nan", _dh_text(dh_alpha="[.nan, 0, 0, 0, 0, 0]"), r"dh_alpha\[0\] is nan"),
    ("inf", _dh_text(dh_d="[.inf, 0, 0, 0, 0, 0]"), r"dh_d\[0\] is inf"),
    ("string", _dh_text(dh_theta="[0, zero, 0, 0, 0, 0]"), r"dh_theta\[1\] is 'zero'; expected a number"),
    ("bool", _dh_text(dh_theta="[0, true, 0, 0, 0, 0]"), r"dh_theta\[1\] is True"),
    ("scalar", _dh_text(dh_a="0.5"), r"dh_a is 0.5; expected a list of 6 numbers"),
    ("not_mapping", "- 1\n- 2\n", r"expected a mapping"),
    ("bad_yaml", "dh_theta: [0, 0\n", r"invalid YAML"),
    (
        "half_pi",
        _dh_text(dh_alpha="[1.570796327, 1.5707963267948966, 0, 1.570796327, -1.570796327, 0]"),
        r"DH joint 2: alpha = .* parallel",
    ),
]


@pytest.mark.parametrize(
    ("text", "message"), [(t, m) for _, t, m in MALFORMED], ids=[i for i, _, _ in MALFORMED]
)
def test_malformed_dh_cli_exit_2_nothing_written(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], text: str, message: str
) -> None:
    dh = tmp_path / "dh.yaml"
    dh.write_text(text)
    out = tmp_path / "out.yaml"
    assert main(["ur", "correct", "--dh", str(dh), "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("error: ")

    assert re.search(message, err[0]), err[0]
    if "parallel" not in message:
        assert str(dh) in err[0]
    assert not out.exists()
    assert list(tmp_path.iterdir()) == [dh]


def test_malformed_deltas_names_file_and_key(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    d = tmp_path / "calibration.conf"
    d.write_text("delta_theta = [0, 0, 0, 0, 0, 0]\ndelta_a = [0, 0, x, 0, 0, 0]\n")
    out = tmp_path / "out.yaml"
    assert main(["ur", "correct", "--model", "ur10e", "--deltas", str(d), "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert f"deltas file {d} line 2: delta_a entry 'x' is not a number" in err
    d.write_text("delta_theta = [0, 0, 0, 0, 0, 0]\n")
    assert main(["ur", "correct", "--model", "ur10e", "--deltas", str(d), "--out", str(out)]) == 2
    assert "missing key delta_a" in capsys.readouterr().err
    assert not out.exists()


def test_missing_parent_dir_and_bad_usage(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "nope" / "k.yaml"
    assert main(["ur", "correct", "--model", "ur5e", "--out", str(out)]) == 2
    assert f"folder {tmp_path / 'nope'} does not exist" in capsys.readouterr().err
    assert main(["ur", "correct", "--out", str(tmp_path / "k.yaml")]) == 2
    assert "missing DH input" in capsys.readouterr().err
    assert main(["ur", "correct", "--model", "ur99", "--out", str(tmp_path / "k.yaml")]) == 2
    assert "unknown UR model 'ur99'" in capsys.readouterr().err
    assert main(["ur", "correct", "--model", "ur5e", "--rpy", "zyx", "--out", str(tmp_path / "k.yaml")]) == 2
    assert "--rpy 'zyx'" in capsys.readouterr().err
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize(
    ("body", "message"),
    [
        ("kinematics:\n  shoulder: {x: 0}\n", "kinematics.shoulder.y is missing"),
        ("other: 1\n", "expected a top-level 'kinematics' mapping"),
    ],
)
def test_read_kinematics_malformed(tmp_path: Path, body: str, message: str) -> None:
    p = tmp_path / "k.yaml"
    p.write_text(body)
    with pytest.raises(FileFormatError, match=message):
        read_kinematics(p)


def test_read_kinematics_quoted_or_bad_hash(tmp_path: Path) -> None:
    text = kinematics_to_text(correct_kinematics(nominal_dh("ur5e")))
    p = tmp_path / "k.yaml"
    p.write_text(text.replace("hash: calib_12788084448423163542", "hash: 12"))
    with pytest.raises(FileFormatError, match=r"kinematics\.hash is 12"):
        read_kinematics(p)
    p.write_text(text.replace("    z: 0.1625", "    z: .nan"))
    with pytest.raises(FileFormatError, match=r"kinematics.shoulder.z is nan"):
        read_kinematics(p)
