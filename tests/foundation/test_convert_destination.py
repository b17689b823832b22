"""``convert`` refuses to overwrite a destination that is not a calibration, by the same rule as ``sweep --out``."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

from robocal.cli.main import main
from robocal.errors import FileFormatError
from robocal.formats import read_calibration, write_calibration
from robocal.formats.calibration import read_existing_output

ROOT = Path(__file__).resolve().parents[2]
CAL = ROOT / "examples" / "lite" / "calibration.yaml"
URDF = ROOT / "examples" / "lite" / "lite_bimanual.urdf"
LITE_JSON = '{"j1": {"id": 1, "direction": 1, "homing_offset": 0.25}}\n'
LEROBOT = '{"pan": {"id": 1, "drive_mode": 0, "homing_offset": 0, "range_min": 0, "range_max": 4095}}\n'

REFUSED = {
    "notes.yaml": ("some notes, not a calibration\n", None, "not a calibration format robocal knows"),
    "notes.json": ("[1, 2, 3]\n", None, "not a calibration format robocal knows"),
    "motors.json": (LEROBOT, "lite-json", "it looks like lerobot"),
    "cal.json": (LITE_JSON, "lite-yaml", "it looks like lite-json"),
    "robot.urdf": (URDF.read_text(), "lite-yaml", "it looks like ros2-transmission"),
    "broken.yaml": ("a: {id: 1, direction: 1, homing_offset: .nan}\n", None, "homing_offset is nan"),
    "bad.yaml": ("a: [unclosed\n", None, "invalid YAML"),
}


@pytest.mark.parametrize("name", list(REFUSED))
def test_convert_refuses_and_changes_nothing(
    tmp_path: Path, name: str, capsys: pytest.CaptureFixture[str]
) -> None:
    content, to, why = REFUSED[name]
    dst = tmp_path / name
    dst.write_text(content)
    args = ["convert", str(CAL), str(dst)] + (["--to", to] if to else [])
    assert main(args) == 2
    err = capsys.readouterr().err
    fmt = to or ("lite-json" if name.endswith(".json") else "lite-yaml")
    assert err.startswith(f"error: destination {dst}: exists but is not a {fmt} calibration file (")
    assert why in err and err.rstrip().endswith("move it away or choose another destination")
    assert dst.read_text() == content
    assert sorted(p.name for p in tmp_path.iterdir()) == [name]  # no backup, no temporary file


@pytest.mark.parametrize("content", ["", "\n\n", "# only a comment\n# and another\n"])
def test_empty_or_comment_only_destination_is_written(tmp_path: Path, content: str) -> None:
    dst = tmp_path / "cal.yaml"
    dst.write_text(content)
    assert main(["convert", str(CAL), str(dst)]) == 0
    assert read_calibration(dst).calibration.is_close(read_calibration(CAL).calibration, atol=0.0)


def test_same_format_destination_is_updated(tmp_path: Path) -> None:
    dst = tmp_path / "cal.json"
    dst.write_text(LITE_JSON)
    assert main(["convert", str(CAL), str(dst), "--to", "lite-json"]) == 0
    assert read_calibration(dst).calibration.is_close(read_calibration(CAL).calibration, atol=0.0)
    assert (tmp_path / "cal.json.bak").read_text() == LITE_JSON


def test_write_calibration_applies_the_rule_too(tmp_path: Path) -> None:
    dst = tmp_path / "x.json"
    dst.write_text(LEROBOT)
    with pytest.raises(FileFormatError, match=r"x\.json: exists but is not a lite-json calibration file"):
        write_calibration(dst, read_calibration(CAL), "lite-json")
    assert dst.read_text() == LEROBOT


@pytest.mark.slow
def test_sweep_and_convert_give_the_same_reason(tmp_path: Path) -> None:
    """One rule: the same file is refused by both commands for the same reason, before any work."""
    dst = tmp_path / "notes.yaml"
    dst.write_text("some notes\n")
    with pytest.raises(FileFormatError) as direct:
        read_existing_output(dst, "lite-yaml", "--out")
    env = {**os.environ, "PYTHONPATH": str(ROOT / "src")}
    sweep = subprocess.run(
        [
            sys.executable,
            "-m",
            "robocal",
            "sweep",
            "--urdf",
            str(URDF),
            "--source",
            f"replay:{tmp_path}/none.csv",
            "--out",
            str(dst),
        ],
        capture_output=True,
        text=True,
        env=env,
        check=False,
    )
    convert = subprocess.run(
        [sys.executable, "-m", "robocal", "convert", str(CAL), str(dst)],
        capture_output=True,
        text=True,
        env=env,
        check=False,
    )
    assert sweep.returncode == convert.returncode == 2
    assert sweep.stderr == f"error: {direct.value}\n"
    assert convert.stderr == sweep.stderr.replace("--out", "destination", 1).replace(
        "choose another --out", "choose another destination"
    )
    assert dst.read_text() == "some notes\n"
