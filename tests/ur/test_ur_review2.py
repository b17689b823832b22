"""Regression tests from the second UR review: real calibration.conf syntax, unknown YAML keys, --rpy case,
all-or-nothing YAML + URDF pair, bounded host-name resolution. Each failed before its fix."""

from __future__ import annotations

import re
import socket
import threading
from pathlib import Path
from typing import Any

import pytest

import robocal.workflows.ur as wf
from robocal.backends.ur_primary import PrimaryClient, resolve_host
from robocal.cli.main import main
from robocal.core.dh import DHParameters
from robocal.core.ur import check_rpy_convention, correct_kinematics, default_kinematics, nominal_dh
from robocal.errors import CalibTimeoutError, DeviceError, UsageError
from robocal.formats.ur_kinematics import kinematics_to_text, read_deltas, read_dh

from .conftest import DELTA_SETS, calibrated_dh
from .test_ur_formats import dh_yaml
from .test_ur_urdf import ur_urdf_text


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


# --- 1. calibration.conf: the controller's real syntax ------------------------------------------------------------


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


# --- 2. unknown keys in a DH or deltas YAML ----------------------------------------------------------------------


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


# --- 3. --rpy in any case; defaults' help -------------------------------------------------------------------------


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


# --- 4. --urdf-in/--urdf-out: all or nothing -----------------------------------------------------------------------


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
    args = [
        "ur",
        "correct",
        "--model",
        "ur10e",
        "--out",
        str(out),
        "--urdf-in",
        str(urdf_in),
        "--urdf-out",
        str(urdf_out),
    ]
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
    args = [
        "ur",
        "correct",
        "--model",
        "ur10e",
        "--out",
        str(out),
        "--urdf-in",
        str(urdf_in),
        "--urdf-out",
        str(urdf_out),
    ]
    assert main(args) == 2
    assert f"cannot write {urdf_out}: Read-only file system" in _one_error_line(capsys.readouterr().err)
    assert {p: (p.read_bytes() if p.exists() else None) for p in before} == before


def test_urdf_pair_success_writes_both(tmp_path: Path) -> None:
    urdf_in, urdf_out, out, _ = _urdf_pair_setup(tmp_path, existing=True)
    args = [
        "ur",
        "correct",
        "--model",
        "ur10e",
        "--rpy",
        "UPSTREAM",
        "--out",
        str(out),
        "--urdf-in",
        str(urdf_in),
        "--urdf-out",
        str(urdf_out),
    ]
    assert main(args) == 0
    assert out.read_text() == kinematics_to_text(correct_kinematics(nominal_dh("ur10e"), "upstream"))
    assert (tmp_path / "cal.yaml.bak").read_text() == "old yaml\n"
    assert (tmp_path / "ur_cal.urdf.bak").read_text() == "old urdf\n"
    assert "shoulder_pan_joint" in urdf_out.read_text()


# --- 5. host-name resolution bounded by --timeout ----------------------------------------------------------------


def test_unresolvable_host_is_one_error_exit_3(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "k.yaml"
    assert main(["ur", "extract", "--host", "nonexistent.invalid", "--out", str(out), "--timeout", "3"]) == 3
    line = _one_error_line(capsys.readouterr().err)
    assert "UR controller nonexistent.invalid:30001: cannot resolve host name 'nonexistent.invalid'" in line
    assert not out.exists()


def test_resolution_that_never_answers_hits_the_timeout(monkeypatch: pytest.MonkeyPatch) -> None:
    release = threading.Event()
    real = socket.getaddrinfo

    def stuck(host: str, *args: Any, **kw: Any) -> Any:
        if kw.get("flags", 0) & socket.AI_NUMERICHOST:
            return real(host, *args, **kw)
        release.wait(30)  # a dead DNS server
        raise socket.gaierror(socket.EAI_AGAIN, "Temporary failure in name resolution")

    monkeypatch.setattr(socket, "getaddrinfo", stuck)
    try:
        with pytest.raises(
            CalibTimeoutError, match=r"cannot resolve host name 'robot\.example' within 0\.2 s"
        ):
            PrimaryClient("robot.example", 30001, 0.2).read_kinematics()
        # numeric addresses never wait for the resolver
        assert resolve_host("127.0.0.1", 30001, 0.2)[0][4] == ("127.0.0.1", 30001)
    finally:
        release.set()


def test_resolver_error_is_a_device_error(monkeypatch: pytest.MonkeyPatch) -> None:
    real = socket.getaddrinfo

    def fails(host: str, *args: Any, **kw: Any) -> Any:
        if kw.get("flags", 0) & socket.AI_NUMERICHOST:
            return real(host, *args, **kw)
        raise socket.gaierror(socket.EAI_NONAME, "Name or service not known")

    monkeypatch.setattr(socket, "getaddrinfo", fails)
    with pytest.raises(
        DeviceError, match=r"cannot resolve host name 'robot\.example' \(Name or service not known\)"
    ):
        resolve_host("robot.example", 30001, 5.0)
