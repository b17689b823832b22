"""An empty path on the command line (``--out "$UNSET"``) is refused, not read as ``.``, the current folder.

typer turns ``""`` into ``Path("")``, which is ``.``: ``--urdf ""`` was then "inside --urdf (.)", ``--out ""`` a
folder, a dataset ROOT ``""`` the folder the command ran in. Every path parameter of every command now refuses it
with one ``error:`` line naming the parameter, exit 2, nothing created.
"""

from __future__ import annotations

from pathlib import Path

import pytest

from robocal.cli.main import main

LITE = Path(__file__).resolve().parents[2] / "examples" / "lite" / "lite_bimanual.urdf"


@pytest.mark.parametrize(
    ("argv", "label"),
    [
        (["dataset", "health", "data", "--report", "r.json", "--urdf", ""], "--urdf"),
        (["dataset", "inspect", ""], "ROOT"),
        (["dataset", "recalibrate", "", "dst", "--old", "a.json", "--new", "b.json"], "SRC"),
        (["sweep", "--urdf", str(LITE), "--source", "sim:lite", "--out", ""], "--out"),
        (["sweep", "--urdf", "", "--source", "sim:lite", "--out", "cal.yaml"], "--urdf"),
        (["convert", "", "out.json"], "SRC"),
        (["convert", "in.json", " "], "DST"),
    ],
)
def test_an_empty_path_is_refused_naming_the_parameter(
    argv: list[str], label: str, tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    monkeypatch.chdir(tmp_path)
    assert main(argv) == 2
    out, err = capsys.readouterr()
    assert out == "" and err.count("error:") == 1 and "Traceback" not in err
    assert err.strip() == f"error: {label}: an empty path (an unset shell variable?); give a file or folder name"
    assert list(tmp_path.iterdir()) == []  # nothing created
