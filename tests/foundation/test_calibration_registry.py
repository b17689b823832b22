"""The calibration format registry (robocal.formats.calibration.registry) is the path for detect/read/write."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from robocal.core import RobotCalibration
from robocal.errors import FileFormatError, UsageError
from robocal.formats import FORMATS, CalibrationFile, detect_format, read_calibration, write_calibration
from robocal.formats.calibration import registry
from robocal.formats.calibration._base import Content, FormatSpec
from robocal.formats.calibration.registry import read_existing_output

CAL = CalibrationFile(RobotCalibration(["a", "b"], [1, -1], [0.5, -0.25]), {"a": 1, "b": 2})


def test_formats_in_help_order_each_from_its_own_module() -> None:
    assert list(FORMATS) == [
        "lite-json",
        "lite-yaml",
        "berkeley-offsets",
        "ros2-transmission",
        "lerobot-legacy",
        "robocal",
        "openarm-lerobot",
        "openarm-ros2",
    ]
    modules = {name: spec.reader.__module__.rsplit(".", 1)[1] for name, spec in FORMATS.items()}
    assert modules == {
        "lite-json": "lite_json",
        "lite-yaml": "lite_yaml",
        "berkeley-offsets": "berkeley",
        "ros2-transmission": "transmission",
        "lerobot-legacy": "lerobot_legacy",
        "robocal": "canonical",
        "openarm-lerobot": "openarm_lerobot",
        "openarm-ros2": "openarm_ros2",
    }
    assert [n for n, s in FORMATS.items() if s.writer is None] == ["lerobot-legacy"]


@pytest.mark.parametrize(
    ("name", "fmt"),
    [
        ("c.json", "lite-json"),
        ("c.yaml", "lite-yaml"),
        ("c.YML", "lite-yaml"),
        ("c.urdf", "ros2-transmission"),
        ("c.xml", "ros2-transmission"),
    ],
)
def test_new_destination_format_comes_from_the_spec_suffixes(tmp_path: Path, name: str, fmt: str) -> None:
    assert write_calibration(tmp_path / name, CAL) == fmt
    assert detect_format(tmp_path / name) == fmt


def test_unknown_suffix_is_a_usage_error_listing_formats(tmp_path: Path) -> None:
    with pytest.raises(UsageError, match=r"cannot tell the format of .*c\.txt.*--to \(lite-json, lite-yaml"):
        write_calibration(tmp_path / "c.txt", CAL)
    assert not (tmp_path / "c.txt").exists()


def test_most_specific_sniffer_wins(tmp_path: Path) -> None:
    # a YAML mapping that has the robocal tag and a position_offsets key is a robocal file (tag, rank 0)
    p = tmp_path / "x.yaml"
    p.write_text("format: robocal-joint-map\nposition_offsets: [1]\n")
    assert detect_format(p) == "robocal"
    # position_offsets beats the shape of a Lite file (rank 1 before rank 2)
    p.write_text(json.dumps({"position_offsets": {"a": 1}}))
    assert detect_format(p) == "berkeley-offsets"
    ranks = {n: s.sniff_rank for n, s in FORMATS.items()}
    assert ranks == {
        "lite-json": 2,
        "lite-yaml": 2,
        "berkeley-offsets": 1,
        "ros2-transmission": 1,
        "lerobot-legacy": 1,
        "robocal": 0,
        "openarm-lerobot": 1,
        "openarm-ros2": 1,
    }


def test_current_lerobot_file_is_recognised_but_not_a_joint_map(tmp_path: Path) -> None:
    p = tmp_path / "so101.json"
    p.write_text(
        json.dumps(
            {"shoulder_pan": {"id": 1, "drive_mode": 0, "homing_offset": 0, "range_min": 1, "range_max": 2}}
        )
    )
    with pytest.raises(FileFormatError, match=r"current LeRobot calibration .* lerobot export-urdf"):
        read_calibration(p)
    with pytest.raises(FileFormatError, match="it looks like lerobot"):
        read_existing_output(p, "lite-json")
    assert [n.name for n in registry.NOT_JOINT_MAPS] == ["lerobot"]


def test_spec_flags_drive_the_existing_output_rule(tmp_path: Path) -> None:
    # self-contained formats are read back before being overwritten; the positional one only recognised
    assert {n for n, s in FORMATS.items() if s.self_contained} == {
        "lite-json", "lite-yaml", "robocal", "openarm-lerobot", "openarm-ros2"
    }
    p = tmp_path / "c.yaml"
    write_calibration(p, CAL, "robocal")
    got = read_existing_output(p, "robocal")
    assert got is not None and got.calibration.joint_names == ("a", "b")
    b = tmp_path / "b.yaml"
    b.write_text("position_offsets: [0.1, 0.2]\n")
    assert read_existing_output(b, "berkeley-offsets") is None


def test_a_sniffer_sees_content_parsed_once() -> None:
    spec = FORMATS["lite-yaml"]
    assert isinstance(spec, FormatSpec)
    assert spec.sniff(Content("yaml", {"j": {"direction": 1}}, "s")) is True
    assert spec.sniff(Content("json", {"j": {"direction": 1}}, "s")) is False
    assert FORMATS["lite-json"].sniff(Content("json", {"j": {"range_min": 1}}, "s")) is False
    with pytest.raises(FileFormatError, match="s: this is a motor configuration"):
        FORMATS["lite-json"].sniff(Content("json", {"j": {"powerstage": {}}}, "s"))
