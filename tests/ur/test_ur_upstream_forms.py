"""UR DH input in every form UR and the ROS drivers write, and the upstream calibrated-kinematics files."""

from __future__ import annotations

import re
from pathlib import Path

import pytest
from tests.robots import UR_LINKS

from robocal.cli.main import main
from robocal.errors import FileFormatError
from robocal.formats.ur_kinematics import read_dh, read_kinematics

FIXTURES = Path(__file__).resolve().parent.parent / "fixtures" / "ur"
DOCS_DH = FIXTURES / "dh_ur_calibration_docs.yaml"
MODELS = ("ur3", "ur5", "ur10", "ur3e", "ur5e", "ur10e", "ur16e", "ur20", "ur30")
# the numbers of the ur_calibration docs' example (algorithm.rst), by key
DOCS_THETA = (
    -2.4147806894359e-07,
    1.60233952386695,
    -1.68607190752171,
    0.0837331147700119,
    -1.01260355871158e-07,
    3.91986209186124e-08,
)
DOCS_D = (
    0.180539811714259,
    439.140974079901,
    -446.027059806332,
    7.0603368964236,
    0.119811341150314,
    0.115670917257426,
)


def _lists(text: str) -> dict[str, list[str]]:
    """The number tokens of each ``key: [ ... ]`` line of the docs file."""
    out = {}
    for line in text.splitlines():
        m = re.match(r"^(dh_\w+):\s*\[(.*)\]\s*$", line)
        if m:
            out[m.group(1)] = m.group(2).split()
    return out


def _commas(lists: dict[str, list[str]]) -> str:
    return "".join(f"{k}: [{', '.join(v)}]\n" for k, v in lists.items())


def _block(lists: dict[str, list[str]]) -> str:
    return "".join(f"{k}:\n" + "".join(f"  - {x}\n" for x in v) for k, v in lists.items())


def _log(lists: dict[str, list[str]], status: int = 2) -> str:
    """The layout ur_client_library's KinematicsInfo::toString() prints, as ur_calibration logs it (ROS 1)."""
    lines = ["[ INFO] [1560953586.352160902]: checksum: [" + "4294967295 " * 6 + "]"]
    lines += [f"{k}: [" + "".join(f"{x} " for x in v) + "]" for k, v in lists.items()]
    lines.append(f"calibration_status: {status}")
    return "\n".join(lines) + "\n\n"


def test_docs_dh_with_spaces_reads_the_printed_numbers() -> None:
    warnings: list[str] = []
    dh = read_dh(DOCS_DH, warnings=warnings)
    assert dh.theta_rad == DOCS_THETA
    assert dh.d_m == DOCS_D
    assert dh.a_m[5] == 0.0 and dh.alpha_rad[5] == 0.0
    assert warnings == []


@pytest.mark.slow
def test_ur_correct_writes_the_same_yaml_for_spaces_commas_block_and_log(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    lists = _lists(DOCS_DH.read_text())
    assert set(lists) == {"dh_theta", "dh_a", "dh_d", "dh_alpha"}
    inputs = {
        "spaces": DOCS_DH,
        "commas": tmp_path / "commas.yaml",
        "block": tmp_path / "block.yaml",
        "log": tmp_path / "driver.log",
        "ros2_log": tmp_path / "driver2.log",
    }
    inputs["commas"].write_text(_commas(lists))
    inputs["block"].write_text(_block(lists))
    inputs["log"].write_text(_log(lists))
    inputs["ros2_log"].write_text(
        _log(lists).replace(
            "[ INFO] [1560953586.352160902]: ", "[INFO] [1700000000.123456789] [ur_calibration]: "
        )
    )
    outputs = {}
    for name, path in inputs.items():
        out = tmp_path / f"{name}_kinematics.yaml"
        code = main(["ur", "correct", "--dh", str(path), "--out", str(out)])
        captured = capsys.readouterr()
        assert code == 0, (name, captured.err)
        assert "warning" not in captured.err, name
        outputs[name] = out.read_bytes()
    assert len(set(outputs.values())) == 1  # byte for byte the same kinematics YAML
    kin = read_kinematics(tmp_path / "spaces_kinematics.yaml")
    assert kin.hash.startswith("calib_")


def test_log_with_status_not_linearised_warns(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    log = tmp_path / "driver.log"
    log.write_text(_log(_lists(DOCS_DH.read_text()), status=1))
    assert main(["ur", "correct", "--dh", str(log), "--out", str(tmp_path / "k.yaml")]) == 1
    assert "calibration_status is 1, not 2 (linearised)" in capsys.readouterr().err


@pytest.mark.parametrize(
    ("value", "message"),
    [
        ("[0 0 0 zero 0 0 ]", r"dh_theta\[3\] is 'zero'; expected a number \(the list is '0 0 0 zero 0 0'\)"),
        (
            "[0, 0 0, 0, 0, 0]",
            r"dh_theta\[1\] is '0 0'; .*separate the 6 numbers all by commas or all by spaces",
        ),
        ("[0 0 0 0 0 ]", r"dh_theta has 5 values \(\[0\.0, 0\.0, 0\.0, 0\.0, 0\.0\]\); expected 6 numbers"),
        ("[0 0 0 0 0 0 0 ]", r"dh_theta has 7 values"),
        (
            "0 0 0 0 0 0",
            r"dh_theta is '0 0 0 0 0 0'; expected a list of 6 numbers \(\[a, b, c, d, e, f\], \[a b c",
        ),
        ("[0 0 0 0 0 nan ]", r"dh_theta\[5\] is nan; expected a finite number"),
        ("{a: 1}", r"dh_theta is \{'a': 1\}; expected a list of 6 numbers"),
    ],
)
def test_malformed_dh_names_the_key_and_what_was_found(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], value: str, message: str
) -> None:
    lists = _lists(DOCS_DH.read_text())
    text = _commas(lists).replace(f"dh_theta: [{', '.join(lists['dh_theta'])}]", f"dh_theta: {value}")
    src = tmp_path / "dh.yaml"
    src.write_text(text)
    with pytest.raises(FileFormatError, match=message) as exc:
        read_dh(src)
    assert "has 1 values" not in str(exc.value)
    out = tmp_path / "k.yaml"
    assert main(["ur", "correct", "--dh", str(src), "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert err.startswith("error: ") and err.count("\n") == 1
    assert not out.exists()


@pytest.mark.parametrize("model", MODELS)
def test_upstream_default_kinematics_verify_against_the_nominal_dh(
    model: str, capsys: pytest.CaptureFixture[str]
) -> None:
    path = FIXTURES / f"{model}_default_kinematics.yaml"
    kin = read_kinematics(path)
    assert re.fullmatch(r"calib_\d+", kin.hash)
    assert [link.name for link in kin.links] == list(UR_LINKS)
    assert main(["ur", "verify", str(path), "--model", model]) == 0
    assert "match" in capsys.readouterr().out


def test_verify_the_calibrated_yaml_of_space_printed_dh(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "k.yaml"
    assert main(["ur", "correct", "--dh", str(DOCS_DH), "--out", str(out)]) == 0
    assert main(["ur", "verify", str(out), "--dh", str(DOCS_DH)]) == 0
    capsys.readouterr()


def test_kinematics_file_errors_say_what_was_found(tmp_path: Path) -> None:
    with pytest.raises(
        FileFormatError, match=r"found keys: dh_theta, dh_a, dh_d, dh_alpha; this is a DH file"
    ):
        read_kinematics(DOCS_DH)
    p = tmp_path / "k.yaml"
    text = (FIXTURES / "ur5e_default_kinematics.yaml").read_text()
    p.write_text(text.replace("  forearm:", "  fore_arm:"))
    with pytest.raises(
        FileFormatError, match=r"kinematics\.forearm is missing \(found: shoulder, upper_arm, fore_arm"
    ):
        read_kinematics(p)
    p.write_text("kinematics:\n  shoulder: [0, 0, 0.1625, 0, 0, 0]\n")
    with pytest.raises(
        FileFormatError, match=r"kinematics\.shoulder is \[0, 0, 0\.1625, 0, 0, 0\]; expected a mapping"
    ):
        read_kinematics(p)
