"""Bad input: a CalibError with a specific message, CLI exit 2 with one ``error:`` line, nothing written."""

from __future__ import annotations

import hashlib
import shutil
from pathlib import Path

import pytest

from robocal.cli.main import main
from robocal.errors import CalibError, FileFormatError
from robocal.formats import read_calibration
from robocal.formats.urdf import read_urdf

EXAMPLES = Path(__file__).resolve().parents[2] / "examples" / "lite"
URDF_TEXT = (EXAMPLES / "lite_bimanual.urdf").read_text()

LITE = {
    "bad_json_syntax": (
        "c.json",
        '{"a": {"id": 1, "direction": 1, "homing_offset": 0.5}',
        "invalid JSON (line 1",
    ),
    "bad_yaml_syntax": ("c.yaml", "a:\n  id: [1\n", "invalid YAML (line"),
    "duplicate_json_key": (
        "c.json",
        '{"a": {"id": 1, "direction": 1, "homing_offset": 0.5}, "a": {}}',
        "duplicate key 'a'",
    ),
    "duplicate_yaml_key": (
        "c.yaml",
        "a: {id: 1, direction: 1, homing_offset: 0.5}\na: {id: 2}\n",
        "duplicate key",
    ),
    "missing_key": ("c.yaml", "a: {id: 1, direction: 1}\n", "joint 'a': missing key homing_offset"),
    "unknown_key": (
        "c.yaml",
        "a: {id: 1, direction: 1, homing_offset: 0.5, homing_ofset: 1}\n",
        "joint 'a': unknown key homing_ofset",
    ),
    "wrong_type_offset": (
        "c.yaml",
        "a: {id: 1, direction: 1, homing_offset: [1]}\n",
        "joint 'a': homing_offset has type CommentedSeq; expected a number",
    ),
    "string_offset": (
        "c.json",
        '{"a": {"id": 1, "direction": 1, "homing_offset": "abc"}}',
        "joint 'a': homing_offset 'abc' is not a number",
    ),
    "bool_direction": (
        "c.json",
        '{"a": {"id": 1, "direction": true, "homing_offset": 0.5}}',
        "joint 'a': direction is True",
    ),
    "nan_offset_yaml": (
        "c.yaml",
        "a: {id: 1, direction: 1, homing_offset: .nan}\n",
        "joint 'a': homing_offset is nan; expected a finite number",
    ),
    "nan_offset_json": (
        "c.json",
        '{"a": {"id": 1, "direction": 1, "homing_offset": NaN}}',
        "c.json:1: joint 'a': homing_offset is NaN; JSON has no NaN or Infinity",
    ),
    "inf_offset": ("c.yaml", "a: {id: 1, direction: 1, homing_offset: .inf}\n", "homing_offset is inf"),
    "direction_zero": (
        "c.yaml",
        "a: {id: 1, direction: 0, homing_offset: 0.5}\n",
        "joint 'a': direction 0 is invalid; expected -1 or 1",
    ),
    "direction_two": (
        "c.json",
        '{"a": {"id": 1, "direction": 2, "homing_offset": 0.5}}',
        "joint 'a': direction 2 is invalid",
    ),
    "duplicate_ids": (
        "c.yaml",
        "a: {id: 1, direction: 1, homing_offset: 0.5}\nb: {id: 1, direction: 1, homing_offset: 0}\n",
        "joints 'a' and 'b' share id 1",
    ),
    "float_id": (
        "c.yaml",
        "a: {id: 1.5, direction: 1, homing_offset: 0.5}\n",
        "joint 'a': id 1.5 is not an integer",
    ),
    "not_a_mapping": ("c.yaml", "- 1\n- 2\n", "unrecognised calibration format"),
    "empty_file": ("c.yaml", "", "unrecognised calibration format"),
    "entry_not_mapping": ("c.json", '{"a": 5}', "unrecognised calibration format"),
}


def _snapshot(folder: Path) -> dict[str, str]:
    return {p.name: hashlib.sha256(p.read_bytes()).hexdigest() for p in sorted(folder.iterdir())}


@pytest.mark.parametrize("case", sorted(LITE))
def test_malformed_calibration_files(tmp_path: Path, case: str, capsys: pytest.CaptureFixture[str]) -> None:
    name, text, message = LITE[case]
    src = tmp_path / name
    src.write_text(text)
    fmt = "lite-json" if name.endswith(".json") else "lite-yaml"
    if message != "unrecognised calibration format":
        with pytest.raises(CalibError, match=message.replace("(", r"\(").replace("[", r"\[")):
            read_calibration(src, fmt)
    # through the CLI: detection on, destination must not be created
    dst = tmp_path / "out.json"
    before = _snapshot(tmp_path)
    code = main(["convert", str(src), str(dst), "--urdf", str(EXAMPLES / "lite_bimanual.urdf")])
    err = capsys.readouterr().err
    assert code == 2
    lines = [ln for ln in err.splitlines() if ln]
    assert len(lines) == 1 and lines[0].startswith("error: ")
    assert str(src) in lines[0]
    assert "Traceback" not in err
    assert _snapshot(tmp_path) == before


URDF_CASES = {
    "truncated": (URDF_TEXT[: len(URDF_TEXT) // 2], "not well-formed XML"),
    "external_entity": (
        '<?xml version="1.0"?>\n<!DOCTYPE robot [<!ENTITY secret SYSTEM "file:///etc/passwd">]>\n'
        '<robot name="r">&secret;</robot>\n',
        "entity declarations are not allowed",
    ),
    "network_entity": (
        '<?xml version="1.0"?>\n<!DOCTYPE robot [<!ENTITY e SYSTEM "http://example.invalid/x">]>\n<robot name="r">&e;</robot>\n',
        "entity declarations are not allowed",
    ),
    "wrong_root": ("<model/>", "root element is <model>, expected <robot>"),
    "bad_limit": (
        URDF_TEXT.replace('lower="-2.356"', 'lower="abc"', 1),
        "joint 'left_elbow_pitch': <limit lower> 'abc'",
    ),
    "nan_limit": (URDF_TEXT.replace('upper="0.785"', 'upper="nan"', 1), "<limit upper> is nan"),
    "duplicate_joint": (
        URDF_TEXT.replace('name="left_wrist_roll" type', 'name="left_wrist_yaw" type'),
        "duplicate joint 'left_wrist_yaw'",
    ),
    "bad_direction_param": (
        URDF_TEXT.replace('<param name="direction">-1</param>', '<param name="direction">0</param>', 1),
        "joint 'left_shoulder_pitch' <param name='direction'>: direction '0' is invalid",
    ),
    "not_xml": ("robot: yes\n", "not well-formed XML"),
}


@pytest.mark.parametrize("case", sorted(URDF_CASES))
def test_malformed_urdf(tmp_path: Path, case: str, capsys: pytest.CaptureFixture[str]) -> None:
    text, message = URDF_CASES[case]
    urdf = tmp_path / "robot.urdf"
    urdf.write_text(text)
    cal = tmp_path / "calibration.yaml"
    shutil.copy(EXAMPLES / "calibration.yaml", cal)
    before = _snapshot(tmp_path)
    code = main(["check", "--calibration", str(cal), "--urdf", str(urdf)])
    err = capsys.readouterr().err
    assert code == 2, err
    lines = [ln for ln in err.splitlines() if ln]
    assert len(lines) == 1 and lines[0].startswith("error: URDF ")
    assert message in lines[0]
    assert _snapshot(tmp_path) == before
    if case != "bad_direction_param":
        with pytest.raises(FileFormatError, match=message.replace("(", r"\(")):
            read_urdf(urdf)


def test_secret_never_leaks_through_entities(tmp_path: Path) -> None:
    secret = tmp_path / "secret.txt"
    secret.write_text("TOPSECRET")
    urdf = tmp_path / "r.urdf"
    urdf.write_text(f'<!DOCTYPE robot [<!ENTITY s SYSTEM "{secret.as_uri()}">]><robot name="&s;"/>')
    with pytest.raises(FileFormatError) as info:
        read_urdf(urdf)
    assert "TOPSECRET" not in str(info.value)


def test_missing_joint_and_unknown_format(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    src = EXAMPLES / "calibration.yaml"
    assert main(["convert", str(src), str(tmp_path / "x.json"), "--joints", "left_elbow_pitch,nope"]) == 2
    assert "joints not in the calibration: nope" in capsys.readouterr().err
    assert main(["convert", str(src), str(tmp_path / "x.json"), "--to", "csv"]) == 2
    assert "unknown format 'csv'; valid: lite-json" in capsys.readouterr().err
    assert main(["convert", str(src), str(tmp_path / "x.bin")]) == 2
    assert "pass --to" in capsys.readouterr().err
    assert main(["convert", str(tmp_path / "absent.yaml"), str(tmp_path / "x.json")]) == 2
    assert "absent.yaml: no such file" in capsys.readouterr().err
    assert main(["convert", str(src), str(tmp_path / "no" / "dir.json")]) == 2
    assert "folder" in capsys.readouterr().err
    assert sorted(p.name for p in tmp_path.iterdir()) == []
