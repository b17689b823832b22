"""robocal.cli.lerobot: one error line, no bus I/O, no file for impossible outputs and bad ids."""

from __future__ import annotations

from pathlib import Path

import pytest

from robocal.cli.main import main

from .conftest import LEGACY

pytestmark = pytest.mark.timeout(60)


# --------------------------------------------------------------------------------------------------- CLI
def _run(args: list[str], capsys: pytest.CaptureFixture[str]) -> tuple[int, list[str], str]:
    code = main(args)
    cap = capsys.readouterr()
    return code, cap.err.strip().splitlines(), cap.out


def test_calibrate_into_a_file_as_folder_is_one_error_line_and_no_bus_io(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    blocker = tmp_path / "blocker"
    blocker.write_text("x")
    args = ["lerobot", "calibrate", "--robot", "so101_follower", "--port", "sim", "--id", "a"]
    code, err, _ = _run([*args, "--calibration-dir", str(blocker)], capsys)
    assert code == 2
    assert len([e for e in err if e.startswith("error:")]) == 1
    assert err[-1].startswith(f"error: cannot write {blocker}/robots/so_follower/a.json")
    assert not any(e.startswith("reading") for e in err)  # refused before the sweep
    (tmp_path / "cal/robots/so_follower/b.json").mkdir(parents=True)
    code, err, _ = _run([*args[:-1], "b", "--calibration-dir", str(tmp_path / "cal")], capsys)
    assert code == 2 and err[-1].endswith("is a directory")
    assert not any(e.startswith("reading") for e in err)
    assert blocker.read_text() == "x"


def test_migrate_out_under_a_file_is_one_error_line(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    src = tmp_path / "legacy.json"
    src.write_text(LEGACY)
    blocker = tmp_path / "blocker"
    blocker.write_text("x")
    code, err, _ = _run(
        ["lerobot", "migrate", str(src), "--vendor", "dynamixel", "--out", str(blocker / "x.json")], capsys
    )
    assert code == 2
    assert err == [f"error: cannot write {blocker}/x.json: {blocker} is not a folder"]


@pytest.mark.parametrize(
    ("ids", "message"),
    [
        ("1,1,2,3,4,5", "error: --ids: motor id 1 is given twice"),
        ("1,2,3,4,5,300", "error: --ids: motor id 300 is outside 0..253"),
        ("1,2,3,4,5,-1", "error: --ids: motor id -1 is outside 0..253"),
    ],
)
def test_migrate_refuses_bad_ids_even_when_printing(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], ids: str, message: str
) -> None:
    src = tmp_path / "legacy.json"
    src.write_text(LEGACY)
    code, err, out = _run(["lerobot", "migrate", str(src), "--vendor", "dynamixel", "--ids", ids], capsys)
    assert code == 2
    assert err == [message]
    assert out == ""
