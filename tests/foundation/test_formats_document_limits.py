"""Every JSON and YAML reader refuses hostile documents with a FileFormatError naming the file, never a crash.

Documents nested thousands of levels deep (RecursionError inside the parsers), lone surrogates in names
(invalid Unicode), NaN/Infinity in JSON (with line and joint), integers of 10**30 in LeRobot files (OverflowError).
"""

from __future__ import annotations

import contextlib
import json
import subprocess
import sys
from collections.abc import Callable
from pathlib import Path
from typing import Any

import pytest

from robocal.core.jointmap import RobotCalibration
from robocal.core.lerobot import LegacyCalibration
from robocal.errors import CalibError, FileFormatError, InvalidCalibrationError
from robocal.formats import read_calibration, write_calibration
from robocal.formats.calibration import detect_format
from robocal.formats.lerobot import parse_current, read_current, read_legacy, write_legacy
from robocal.formats.ur_kinematics import read_deltas, read_dh, read_kinematics

N = 5_000
DEEP_JSON = "[" * N + "]" * N
DEEP_JSON_OBJ = '{"a":' * N + "1" + "}" * N
DEEP_YAML_BLOCK = "".join("  " * i + "a:\n" for i in range(2000))  # 4 MB: under the 8 MiB document limit

LITE_JSON_READERS: dict[str, Callable[[Path], Any]] = {
    "detect": detect_format,
    "lite-json": lambda p: read_calibration(p, "lite-json"),
    "auto": read_calibration,
    "berkeley-json": lambda p: read_calibration(p, "berkeley-offsets", joint_order=["a"]),
    "lerobot-current": read_current,
    "lerobot-legacy": read_legacy,
}
YAML_READERS: dict[str, Callable[[Path], Any]] = {
    "detect": detect_format,
    "lite-yaml": lambda p: read_calibration(p, "lite-yaml"),
    "robocal": lambda p: read_calibration(p, "robocal"),
    "berkeley": lambda p: read_calibration(p, "berkeley-offsets", joint_order=["a"]),
    "ur-dh": read_dh,
    "ur-deltas": read_deltas,
    "ur-kinematics": read_kinematics,
}


@pytest.mark.parametrize("doc", [DEEP_JSON, DEEP_JSON_OBJ], ids=["arrays", "objects"])
@pytest.mark.parametrize("reader", list(LITE_JSON_READERS))
def test_deep_json_in_every_json_reader(tmp_path: Path, reader: str, doc: str) -> None:
    p = tmp_path / "deep.json"
    p.write_text(doc)
    with pytest.raises(FileFormatError, match=r"deep\.json.*(nested more than 100 levels deep|invalid)"):
        LITE_JSON_READERS[reader](p)


@pytest.mark.parametrize("doc", [DEEP_JSON, DEEP_YAML_BLOCK, "a: " + "[" * 150 + "]" * 150 + "\n"])
@pytest.mark.parametrize("reader", list(YAML_READERS))
def test_deep_yaml_in_every_yaml_reader(tmp_path: Path, reader: str, doc: str) -> None:
    p = tmp_path / "deep.yaml"
    p.write_text(doc)
    with pytest.raises(FileFormatError, match=r"deep\.yaml"):
        YAML_READERS[reader](p)
    if doc is not DEEP_JSON:  # a YAML document: refused for its depth, not for its shape
        with pytest.raises(FileFormatError, match="nested more than 100 levels deep"):
            YAML_READERS[reader](p)


def test_dataset_metadata_too_deep(tmp_path: Path) -> None:
    from robocal.dataset._layout import read_layout
    from robocal.dataset._metadata import _read_stats

    (tmp_path / "meta").mkdir()
    (tmp_path / "meta" / "info.json").write_text('{"features": ' + DEEP_JSON + "}")
    with pytest.raises(FileFormatError, match=r"info\.json: nested more than 100 levels deep"):
        read_layout(tmp_path)
    (tmp_path / "meta" / "info.json").write_text('{"features": {}, "total_frames": ' + "9" * 5000 + "}")
    with pytest.raises(
        FileFormatError, match=r"info\.json: invalid JSON \(line 1, column 34\): an integer of 5000 digits; robocal"
    ):
        read_layout(tmp_path)
    (tmp_path / "stats.json").write_text(DEEP_JSON)
    with pytest.raises(FileFormatError, match=r"stats\.json: nested more than 100 levels deep"):
        _read_stats(tmp_path / "stats.json")


def test_nan_in_json_names_file_line_and_joint(tmp_path: Path) -> None:
    p = tmp_path / "cal.json"
    p.write_text(
        '{\n  "a": {"id": 1, "direction": 1, "homing_offset": 0.5},\n'
        '  "b": {"id": 2, "direction": 1,\n         "homing_offset": -Infinity}\n}\n'
    )
    with pytest.raises(FileFormatError) as info:
        read_calibration(p)
    assert str(info.value) == (
        f"{p}:4: joint 'b': homing_offset is -Infinity; JSON has no NaN or Infinity, expected a finite number"
    )
    # a NaN spelled inside a string is a string, not the constant: the line counts the real one
    p.write_text(
        '{"NaN": {"id": 1, "direction": 1, "homing_offset": 0.5},\n "b": {"id": 2, "direction": 1, '
        '"homing_offset": NaN}}'
    )
    with pytest.raises(FileFormatError, match=r"cal\.json:2: joint 'b': homing_offset is NaN"):
        read_calibration(p, "lite-json")
    q = tmp_path / "motors.json"
    q.write_text(
        '{"shoulder_pan": {"id": 1, "drive_mode": 0, "homing_offset": NaN, "range_min": 0, '
        '"range_max": 4095}}'
    )
    with pytest.raises(FileFormatError, match=r"motors\.json:1: motor 'shoulder_pan': homing_offset is NaN"):
        read_current(q)


def test_lone_surrogates_refused_by_readers(tmp_path: Path) -> None:
    j = tmp_path / "s.json"
    j.write_text(
        '{"ok": {"id": 1, "direction": 1, "homing_offset": 0.5},\n'
        ' "bad\\ud800": {"id": 2, "direction": 1, "homing_offset": 0.5}}'
    )
    for reader in (read_calibration, lambda p: read_calibration(p, "lite-json")):
        with pytest.raises(FileFormatError, match=r"s\.json: joint name 'bad\\ud800' is not valid Unicode"):
            reader(j)
    y = tmp_path / "s.yaml"
    y.write_text(
        'ok: {id: 1, direction: 1, homing_offset: 0.5}\n"bad\\uDC00": {id: 2, direction: 1, '
        "homing_offset: 0.5}\n"
    )
    with pytest.raises(FileFormatError, match=r"s\.yaml:2: joint name 'bad\\udc00' is not valid Unicode"):
        read_calibration(y)
    legacy = {
        "homing_offset": [0],
        "drive_mode": [0],
        "start_pos": [0],
        "end_pos": [100],
        "calib_mode": ["DEGREE"],
        "motor_names": ["m\ud83d"],
    }
    lp = tmp_path / "legacy.json"
    lp.write_text(json.dumps(legacy))
    with pytest.raises(FileFormatError, match=r"legacy\.json: key 'motor_names': \[0\]: the text 'm\\ud83d'"):
        read_legacy(lp)
    # a proper surrogate pair is a real character and is fine
    ok = tmp_path / "pair.json"
    ok.write_text('{"arm\\ud83d\\ude00": {"id": 1, "direction": 1, "homing_offset": 0.5}}')
    assert read_calibration(ok).calibration.joint_names == ("arm\U0001f600",)


@pytest.mark.parametrize("fmt", ["lite-json", "lite-yaml", "robocal", "berkeley-offsets"])
def test_lone_surrogates_refused_by_writers(tmp_path: Path, fmt: str) -> None:
    cal = RobotCalibration(["ok", "bad\udcff"], [1, 1], [0.1, 0.2])
    with pytest.raises(InvalidCalibrationError, match=r"joint name 'bad\\udcff' is not valid Unicode"):
        write_calibration(tmp_path / "out", cal, fmt, ids={"ok": 1, "bad\udcff": 2})
    assert list(tmp_path.iterdir()) == []
    legacy = LegacyCalibration(["m\ud800"], [0], [0], [0], [100], ["DEGREE"])
    with pytest.raises(FileFormatError, match="not valid Unicode"):
        write_legacy(tmp_path / "legacy.json", legacy)
    assert list(tmp_path.iterdir()) == []


def test_huge_integers_in_lerobot_files(tmp_path: Path) -> None:
    legacy = {
        "homing_offset": [0, 10**30],
        "drive_mode": [0, 0],
        "start_pos": [0, 0],
        "end_pos": [100, 100],
        "calib_mode": ["DEGREE", "DEGREE"],
        "motor_names": ["pan", "lift"],
    }
    p = tmp_path / "legacy.json"
    p.write_text(json.dumps(legacy))
    with pytest.raises(FileFormatError) as info:
        read_legacy(p)
    assert str(info.value) == (
        f"{p}: key homing_offset[1] is an integer of 31 digits; expected an integer within ±2147483647 "
        "(a 32-bit register) (motor 'lift')"
    )
    text = json.dumps(
        {"pan": {"id": 1, "drive_mode": 0, "homing_offset": 0, "range_min": -(10**30), "range_max": 4095}}
    )
    with pytest.raises(FileFormatError, match=r"motor 'pan': field range_min is an integer of 31 digits"):
        parse_current(text, "cur.json")
    with pytest.raises(InvalidCalibrationError, match=r"homing_offset .* is not a list of 64-bit integers"):
        LegacyCalibration(["a"], [10**30], [0], [0], [100], ["DEGREE"])


@pytest.mark.slow
@pytest.mark.parametrize(
    ("name", "content", "message"),
    [
        ("deep.json", DEEP_JSON, "deep.json: nested more than 100 levels deep"),
        ("deep.yaml", DEEP_YAML_BLOCK, "deep.yaml: nested more than 100 levels deep"),
        (
            "nan.json",
            '{"j": {"id": 1, "direction": 1,\n"homing_offset": NaN}}',
            "nan.json:2: joint 'j': homing_offset is NaN",
        ),
        (
            "s.json",
            '{"j\\udfff": {"id": 1, "direction": 1, "homing_offset": 0.5}}',
            "joint name 'j\\udfff' is not valid",
        ),
    ],
)
def test_cli_convert_and_check_say_one_error_line(
    tmp_path: Path, name: str, content: str, message: str
) -> None:
    (tmp_path / name).write_text(content)
    urdf = str(Path(__file__).resolve().parents[2] / "examples" / "lite" / "lite_bimanual.urdf")
    for args in (["convert", name, "out.yaml"], ["check", "--calibration", name, "--urdf", urdf]):
        r = subprocess.run(
            [sys.executable, "-m", "robocal", *args],
            cwd=tmp_path,
            capture_output=True,
            text=True,
            check=False,
        )
        assert r.returncode == 2, r.stderr
        assert r.stderr.startswith("error: ") and message in r.stderr
        assert len(r.stderr.splitlines()) == 1 and "Traceback" not in r.stderr
    assert sorted(p.name for p in tmp_path.iterdir()) == [name]


def test_cli_legacy_huge_integer(tmp_path: Path) -> None:
    legacy = {
        "homing_offset": [10**30],
        "drive_mode": [0],
        "start_pos": [0],
        "end_pos": [100],
        "calib_mode": ["DEGREE"],
        "motor_names": ["pan"],
    }
    (tmp_path / "l.json").write_text(json.dumps(legacy))
    r = subprocess.run(
        [sys.executable, "-m", "robocal", "convert", "l.json", "o.yaml"],
        cwd=tmp_path,
        capture_output=True,
        text=True,
        check=False,
    )
    assert r.returncode == 2
    assert r.stderr == (
        "error: l.json: key homing_offset[0] is an integer of 31 digits; expected an integer within ±2147483647 "
        "(a 32-bit register) (motor 'pan')\n"
    )


def test_calib_error_is_the_only_exception(tmp_path: Path) -> None:
    """A spot check over odd Unicode in otherwise valid files: reads succeed or raise CalibError only."""
    for key in ("\u0000", "\ufeff", "\u202e", "a\udc80", "\U0010ffff", "é"):
        p = tmp_path / "c.json"
        p.write_text(json.dumps({key: {"id": 1, "direction": 1, "homing_offset": 0.5}}))
        with contextlib.suppress(CalibError):
            read_calibration(p)


@pytest.mark.parametrize(
    ("name", "content", "message"),
    [
        (
            "o.yaml",
            "a:\n  id: 1\n  direction: 1\n  homing_offset: " + "9" * 400 + "\n",
            "joint 'a': homing_offset is an integer of 400 digits; expected a finite number",
        ),
        (
            "o.json",
            '{"a": {"id": 1, "direction": 1, "homing_offset": ' + "9" * 400 + "}}",
            "joint 'a': homing_offset is an integer of 400 digits; expected a finite number",
        ),
        (
            "d.yaml",
            "a:\n  id: 1\n  direction: " + "9" * 400 + "\n  homing_offset: 0.5\n",
            "direction <an integer of 400 digits> is invalid; expected -1 or 1",
        ),
        (
            "l.json",
            '{"a": {"id": 1, "direction": 1, "homing_offset": ' + "9" * 5000 + "}}",
            "invalid JSON (line 1, column 50): an integer of 5000 digits; robocal reads integers of at most 4300 "
            "digits",
        ),
        (
            "l.yaml",
            "a:\n  id: 1\n  direction: 1\n  homing_offset: " + "9" * 5000 + "\n",
            "invalid YAML (line 4, column 18): an integer of 5000 digits; robocal reads integers of at most 4300 "
            "digits",
        ),
    ],
)
def test_huge_numbers_in_calibration_files(tmp_path: Path, name: str, content: str, message: str) -> None:
    p = tmp_path / name
    p.write_text(content)
    with pytest.raises(FileFormatError) as info:
        read_calibration(p)
    assert str(info.value).startswith(str(p)) and message in str(info.value)


@pytest.mark.parametrize("python_limit", [None, 0, 5000], ids=["default", "no-limit", "raised"])
@pytest.mark.parametrize(
    ("name", "content", "where"),
    [
        ("h.json", '{"a": {"id": 1, "direction": 1, "homing_offset": ' + "9" * 4301 + "}}", "JSON (line 1, column 50)"),
        ("h.yaml", "a:\n  id: 1\n  direction: 1\n  homing_offset: -" + "9" * 4301 + "\n", "YAML (line 4, column 18)"),
    ],
)
def test_huge_integer_is_worded_by_robocal_whatever_pythons_limit(
    tmp_path: Path, python_limit: int | None, name: str, content: str, where: str
) -> None:
    """Issue 27 item 6: Python's own refusal (its limit, its words) differs between versions and asks to change
    Python's settings; robocal words it, the same whether Python has no limit (before 3.10.7, or set to 0) or a
    higher one. 4300 digits are still read."""
    before = getattr(sys, "get_int_max_str_digits", lambda: None)()
    if python_limit is not None:
        if before is None:  # pragma: no cover - Python before 3.10.7: no limit at all
            pytest.skip("this Python has no integer string limit")
        sys.set_int_max_str_digits(python_limit)
    try:
        p = tmp_path / name
        p.write_text(content)
        with pytest.raises(FileFormatError) as info:
            read_calibration(p)
        assert str(info.value) == (
            f"{p}: invalid {where}: an integer of 4301 digits; robocal reads integers of at most 4300 digits"
        )
        p.write_text(content.replace("9" * 4301, "9" * 4300))
        with pytest.raises(FileFormatError, match="homing_offset is an integer of 4300 digits; expected a finite"):
            read_calibration(p)  # read, then refused by the field's own check
    finally:
        if before is not None:
            sys.set_int_max_str_digits(before)
