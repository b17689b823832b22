"""Numbers read from files: motor ids in range, and error messages that stay short whatever a file holds."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from robocal.cli.main import main
from robocal.core.jointmap import JointMap
from robocal.errors import FileFormatError, InvalidCalibrationError
from robocal.formats._numbers import MAX_MOTOR_ID, parse_direction, parse_motor_id, shown


@pytest.mark.parametrize(
    ("value", "expected"),
    [(0, 0), (1, 1), (127, 127), ("0x7f", 127), (253.0, 253), (MAX_MOTOR_ID, MAX_MOTOR_ID)],
)
def test_motor_ids_in_range_are_read(value: object, expected: int) -> None:
    assert parse_motor_id(value, "f") == expected


@pytest.mark.parametrize("value", [-1, MAX_MOTOR_ID + 1, 10**30, "-5"])
def test_motor_ids_out_of_range_are_refused(value: object) -> None:
    with pytest.raises(
        FileFormatError, match=r"^f: id .* is out of range; expected a motor id from 0 to 536870911$"
    ):
        parse_motor_id(value, "f")


def test_a_400_digit_direction_is_named_by_its_length() -> None:
    with pytest.raises(FileFormatError) as err:
        parse_direction(int("1" * 400), "f: joint 'a'")
    assert str(err.value) == "f: joint 'a': direction <an integer of 400 digits> is invalid; expected -1 or 1"


def test_core_direction_check_survives_a_huge_integer() -> None:
    with pytest.raises(InvalidCalibrationError) as err:
        JointMap(direction=10**400, homing_offset=0.0)  # type: ignore[arg-type]
    assert "is invalid; expected -1 or +1" in str(err.value)
    assert len(str(err.value)) < 120


def test_shown_cuts_long_text() -> None:
    assert shown("x" * 100) == "'" + "x" * 38 + "…"
    assert shown(5) == "5"


@pytest.mark.parametrize(
    ("entry", "message"),
    [
        (
            {"id": 10**30, "direction": 1, "homing_offset": 0.1},
            "id 1000000000000000000000000000000 is out of range",
        ),
        ({"id": -5, "direction": 1, "homing_offset": 0.1}, "id -5 is out of range"),
        (
            {"id": 1, "direction": int("1" * 400), "homing_offset": 0.1},
            "direction <an integer of 400 digits>",
        ),
    ],
)
def test_cli_refuses_bad_lite_json_numbers_with_one_line(
    tmp_path: Path, entry: dict[str, int], message: str, capsys: pytest.CaptureFixture[str]
) -> None:
    src = tmp_path / "in.json"
    src.write_text(json.dumps({"leg_left_hip_roll_joint": entry}))
    code = main(["convert", str(src), str(tmp_path / "out.yaml"), "--to", "lite-yaml"])
    err = capsys.readouterr().err
    assert code == 2
    assert message in err
    assert err.count("\n") == 1 and err.startswith("error: ")
    assert not (tmp_path / "out.yaml").exists()


def test_a_file_over_the_input_limit_is_named_as_too_large(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    import robocal.fileio as fileio
    import robocal.fileio.read as fileio_read

    monkeypatch.setattr(fileio_read, "MAX_FILE_BYTES", 10)  # the limit read_bytes applies
    big = tmp_path / "robot.urdf"
    big.write_bytes(b"x" * 11)
    with pytest.raises(FileFormatError) as err:
        fileio.read_bytes(big, "URDF")
    assert str(err.value) == f"URDF {big}: 11 bytes is larger than robocal's 10 byte input limit"
