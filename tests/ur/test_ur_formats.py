"""Kinematics YAML writer/reader, DH and deltas inputs, the malformed-input matrix through the CLI."""

from __future__ import annotations

import re
from pathlib import Path

import pytest
from hypothesis import given
from tests.robots import UR_LINKS

from robocal.cli.main import main
from robocal.core.dh import DHParameters
from robocal.core.ur import correct_kinematics, default_kinematics, nominal_dh
from robocal.errors import FileFormatError
from robocal.formats.ur_kinematics import (
    kinematics_to_text,
    read_deltas,
    read_dh,
    read_kinematics,
    write_kinematics,
)

from .conftest import DELTA_SETS, calibrated_dh
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
    assert [ln.strip()[:-1] for ln in lines if ln.startswith("  ") and not ln.startswith("    ")][:6] == list(UR_LINKS)
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


@pytest.mark.slow
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


def test_hash_beyond_uint64_refused(tmp_path: Path) -> None:
    text = kinematics_to_text(default_kinematics("ur5e"))
    p = tmp_path / "k.yaml"
    p.write_text(text.replace("calib_12788084448423163542", "calib_18446744073709551616"))
    with pytest.raises(FileFormatError, match=r"kinematics\.hash is 'calib_18446744073709551616'"):
        read_kinematics(p)
    p.write_text(text.replace("calib_12788084448423163542", "calib_18446744073709551615"))
    assert read_kinematics(p).hash == "calib_18446744073709551615"


def test_kinematics_file_passed_as_dh_says_so(tmp_path: Path) -> None:
    p = tmp_path / "cal.yaml"
    write_kinematics(p, default_kinematics("ur5e"))
    with pytest.raises(FileFormatError, match=r"is a kinematics YAML \(robocal ur correct output\)"):
        read_dh(p)


def test_conf_with_a_key_twice_is_refused(tmp_path: Path) -> None:
    from robocal.formats.ur_kinematics import read_deltas

    conf = tmp_path / "calibration.conf"
    zeros = "[0, 0, 0, 0, 0, 0]"
    conf.write_text(
        f"[mounting]\ndelta_theta = {zeros}\ndelta_a = {zeros}\ndelta_d = {zeros}\n"
        f"delta_alpha = {zeros}\ndelta_d = [0, 1, 0, 0, 0, 0]\n"
    )
    with pytest.raises(
        FileFormatError, match=rf"deltas file {conf} line 6: delta_d appears twice \(first on line 4\)"
    ):
        read_deltas(conf)


def _one_error_line(err: str) -> str:
    lines = err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: "), lines
    return lines[0]


def _set3_deltas() -> DHParameters:
    _, d, a, th, al = DELTA_SETS[3]
    return DHParameters(theta_rad=tuple(th), a_m=tuple(a), d_m=tuple(d), alpha_rad=tuple(al))


def _conf_list(values: tuple[float, ...]) -> str:
    return "[ " + ", ".join(repr(v) for v in values) + "]"


def real_layout_conf(deltas: DHParameters) -> str:
    """A calibration.conf laid out like the controller's dumps in public issues (ur_modern_driver#179,
    pyrobotlab#145): [mounting], one list per line, hex checksums, a trailing comment, scalar entries."""
    return (
        "[mounting]\n"
        f"delta_theta = {_conf_list(deltas.theta_rad)}\n"
        f"delta_a = {_conf_list(deltas.a_m)}\n"
        f"delta_d = {_conf_list(deltas.d_m)}\n"
        f"delta_alpha = {_conf_list(deltas.alpha_rad)}\n"
        "joint_checksum = [ 0x1a2b3c4d, 0x1a2b3c4e, 0x1a2b3c4f, 0x1a2b3c50, 0x1a2b3c51, 0x1a2b3c52]\n"
        "calibration_status = 2 # 0 == notInitialized / 1 == notLinearised / 2 == Linearised\n"
        "joint_raw_offset = [ 3.1, 3.2, -3.1, 2.3, 2.4, 2.5]\n"
        "joint_selftest_data_crc = [ 0x72b4809f, 0x70928096, 0x68c38696, 0x68bd867b, 0x689f8651, 0x68c4866d]\n"
        "file_save_count = 1\n"
    )


_Z = "0, 0, 0, 0, 0, 0"


_TAIL = f"delta_a = [{_Z}]\ndelta_d = [{_Z}]\ndelta_alpha = [{_Z}]\n"


MALFORMED_CONF = [
    (
        "unclosed_at_eof",
        f"[mounting]\n{_TAIL}delta_theta = [ 0, 0, 0,\n  0, 0, 0\n",
        r"line 5: the list of delta_theta is not closed with '\]' before the end of the file",
    ),
    (
        "unclosed_before_next_key",
        f"[mounting]\ndelta_theta = [ 0, 0, 0,\n0, 0, 0\n{_TAIL}",
        r"line 2: the list of delta_theta is not closed with '\]' before line 4",
    ),
    (
        "empty_entry",
        f"[mounting]\ndelta_theta = [0, 0,, 0, 0, 0, 0]\n{_TAIL}",
        r"line 2: delta_theta has an empty entry \(stray comma\)",
    ),
    (
        "trailing_comma",
        f"[mounting]\ndelta_theta = [0, 0, 0,\n 0, 0, 0,\n]\n{_TAIL}",
        r"line 4: delta_theta ends with a comma",
    ),
    (
        "text_after_list",
        f"[mounting]\ndelta_theta = [{_Z}] 7\n{_TAIL}",
        r"line 2: unexpected '7' after the list of delta_theta",
    ),
    (
        "garbage_line",
        f"[mounting]\ndelta_theta = [{_Z}]\nthis is not a setting\n{_TAIL}",
        r"line 3: expected 'key = value', 'key = \[ \.\.\. \]' or a \[section\]; got 'this is not a setting'",
    ),
    (
        "nested_bracket",
        f"[mounting]\ndelta_theta = [0, [0], 0, 0, 0, 0]\n{_TAIL}",
        r"line 2: delta_theta has a '\[' inside its list",
    ),
    (
        "bad_entry_on_continuation_line",
        f"[mounting]\ndelta_theta = [0, 0, 0,\n 0, x, 0]\n{_TAIL}",
        r"line 3: delta_theta entry 'x' is not a number",
    ),
    (
        "scalar_delta",
        f"[mounting]\ndelta_theta = 0\n{_TAIL}",
        r"delta_theta is '0'; expected a list of 6 numbers",
    ),
    (
        "five_values_over_two_lines",
        f"[mounting]\ndelta_theta = [0, 0, 0,\n 0, 0]\n{_TAIL}",
        r"delta_theta has 5 values \(\[0\.0, 0\.0, 0\.0, 0\.0, 0\.0\]\); expected 6",
    ),
]


def test_conf_with_hex_checksums_and_comments_reads_like_the_deltas(tmp_path: Path) -> None:
    # joint_checksum = [ 0x... ] used to be refused ("entry '0x1a2b3c4d' is not a number")
    conf = tmp_path / "calibration.conf"
    conf.write_text(real_layout_conf(_set3_deltas()))
    assert read_deltas(conf) == _set3_deltas()


def test_conf_lists_spread_over_several_lines(tmp_path: Path) -> None:
    # a list continued on the next lines used to read as "missing key delta_theta"
    d = _set3_deltas()
    th = [repr(v) for v in d.theta_rad]
    conf = tmp_path / "calibration.conf"
    conf.write_text(
        "[mounting]\n"
        f"delta_theta = [ {th[0]}, {th[1]},\n"
        f"    {th[2]}, {th[3]},  # wrapped\n"
        "\n"
        f"    {th[4]}, {th[5]}\n"
        "  ]\n"
        f"delta_a = [\n  {', '.join(repr(v) for v in d.a_m)}\n]\n"
        f"delta_d = {_conf_list(d.d_m)}\n"
        f"delta_alpha = [ {', '.join(repr(v) for v in d.alpha_rad[:3])},\n"
        f"  {', '.join(repr(v) for v in d.alpha_rad[3:])}]\n"
        "joint_checksum = [ 0x1, 0x2, 0x3,\n  0x4, 0x5, 0x6]\n"
        "calibration_status = 2\n"
    )
    assert read_deltas(conf) == d


def test_conf_cli_gives_the_same_file_as_the_dh_yaml(tmp_path: Path) -> None:
    conf = tmp_path / "calibration.conf"
    conf.write_text(real_layout_conf(_set3_deltas()))
    dh = tmp_path / "dh.yaml"
    dh.write_text(dh_yaml(calibrated_dh(3)))
    a, b = tmp_path / "a.yaml", tmp_path / "b.yaml"
    assert main(["ur", "correct", "--model", "ur10e", "--deltas", str(conf), "--out", str(a)]) == 0
    assert main(["ur", "correct", "--dh", str(dh), "--out", str(b)]) == 0
    assert a.read_text() == b.read_text()
    assert a.read_text() == kinematics_to_text(correct_kinematics(calibrated_dh(3)))


@pytest.mark.parametrize(
    ("text", "message"), [(t, m) for _, t, m in MALFORMED_CONF], ids=[i for i, _, _ in MALFORMED_CONF]
)
def test_malformed_conf_exit_2_names_line_nothing_written(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], text: str, message: str
) -> None:
    conf = tmp_path / "calibration.conf"
    conf.write_text(text)
    out = tmp_path / "out.yaml"
    assert main(["ur", "correct", "--model", "ur10e", "--deltas", str(conf), "--out", str(out)]) == 2
    line = _one_error_line(capsys.readouterr().err)
    assert f"deltas file {conf}" in line
    assert re.search(message, line), line
    assert sorted(tmp_path.iterdir()) == [conf]


def test_conf_typo_in_a_key_is_named(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    conf = tmp_path / "calibration.conf"
    conf.write_text(f"[mounting]\ndelta_thetta = [{_Z}]\n{_TAIL}")
    out = tmp_path / "out.yaml"
    assert main(["ur", "correct", "--model", "ur10e", "--deltas", str(conf), "--out", str(out)]) == 2
    assert "missing key delta_theta" in (line := _one_error_line(capsys.readouterr().err))
    assert "found 'delta_thetta' instead (a typo?)" in line
    assert not out.exists()


def test_dh_yaml_unknown_key_warns_exit_1(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    dh = tmp_path / "dh.yaml"
    dh.write_text(dh_yaml(calibrated_dh(3)) + "dh_alhpa: [0, 0, 0, 0, 0, 0]\n")
    out = tmp_path / "out.yaml"
    assert main(["ur", "correct", "--dh", str(dh), "--out", str(out)]) == 1
    err = capsys.readouterr().err.strip().splitlines()
    assert err == [
        f"warning: DH file {dh}: unknown key 'dh_alhpa' ignored (did you mean dh_alpha?); "
        "expected only dh_theta, dh_a, dh_d, dh_alpha"
    ]
    assert out.read_text() == kinematics_to_text(correct_kinematics(calibrated_dh(3)))  # usable: written
    warnings: list[str] = []
    assert read_dh(dh, warnings=warnings) == calibrated_dh(3)
    assert len(warnings) == 1 and "'dh_alhpa'" in warnings[0]


def test_dh_yaml_typo_instead_of_key_is_refused(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    dh = tmp_path / "dh.yaml"
    dh.write_text(dh_yaml(calibrated_dh(3)).replace("dh_alpha:", "dh_alhpa:"))
    out = tmp_path / "out.yaml"
    assert main(["ur", "correct", "--dh", str(dh), "--out", str(out)]) == 2
    line = _one_error_line(capsys.readouterr().err)
    assert line.endswith(
        "missing key dh_alpha (expected dh_theta, dh_a, dh_d, dh_alpha); found 'dh_alhpa' instead (a typo?)"
    )
    assert not out.exists()


@pytest.mark.slow
def test_deltas_yaml_unknown_key_warns_in_correct_verify_and_plot(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    deltas = tmp_path / "deltas.yaml"
    deltas.write_text(
        f"delta_theta: [{_Z}]\ndelta_a: [{_Z}]\ndelta_d: [{_Z}]\ndelta_alpha: [{_Z}]\n"
        "comment: from the pendant\n"
    )
    out = tmp_path / "k.yaml"
    expected = f"warning: deltas file {deltas}: unknown key 'comment' ignored; expected only delta_theta"
    assert main(["ur", "correct", "--model", "ur5e", "--deltas", str(deltas), "--out", str(out)]) == 1
    assert capsys.readouterr().err.startswith(expected)
    assert main(["ur", "verify", str(out), "--model", "ur5e", "--deltas", str(deltas), "--samples", "5"]) == 1
    assert capsys.readouterr().err.strip().splitlines()[0].startswith(expected)
    fig = tmp_path / "f.png"
    assert main(["ur", "plot", "--model", "ur5e", "--deltas", str(deltas), "--out", str(fig)]) == 1
    assert capsys.readouterr().err.startswith(expected)
    assert fig.stat().st_size > 0


def test_conf_extra_entries_are_not_warnings(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    conf = tmp_path / "calibration.conf"
    conf.write_text(real_layout_conf(_set3_deltas()))
    out = tmp_path / "k.yaml"
    assert main(["ur", "correct", "--model", "ur10e", "--deltas", str(conf), "--out", str(out)]) == 0
    assert "warning" not in capsys.readouterr().err
