"""The file map of docs/design.md names files that exist (issue 16: a newcomer finds a system's files in one read)."""

from __future__ import annotations

import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
SRC = ROOT / "src" / "robocal"


def _file_map() -> str:
    text = (ROOT / "docs" / "design.md").read_text()
    start = text.index("\n## File map\n")
    end = text.index("\n## ", start + 1)
    return text[start:end]


def _paths(section: str) -> list[str]:
    """The backticked paths (with a ``/``) in the ``file`` column (the second cell) of the map's table rows."""
    paths: list[str] = []
    for line in section.splitlines():
        cells = line.split("|")
        if line.startswith("|") and len(cells) > 3:
            paths += [
                t
                for t in re.findall(r"`([^`\s]+)`", cells[2])
                if ("/" in t and "(" not in t) or (SRC / t).is_file()
            ]
    return paths


def _exists(path: str) -> bool:
    base = ROOT if path.startswith(("tests/", "docs/")) else SRC
    return (base / path).exists()


def test_every_path_in_the_file_map_exists() -> None:
    paths = _paths(_file_map())
    missing = [p for p in paths if not _exists(p)]
    assert missing == [], "docs/design.md file map names files that do not exist"
    assert "workflows/sweep/job.py" in paths and "cli/lerobot.py" in paths  # the parser sees the rows


def test_the_check_can_fail() -> None:
    section = "| job | `workflows/no_such_module.py`, `core/sweep.py` | x |\n"
    assert [p for p in _paths(section) if not _exists(p)] == ["workflows/no_such_module.py"]


def test_each_system_has_a_section() -> None:
    headings = re.findall(r"^### (.+)$", _file_map(), flags=re.MULTILINE)
    for system in ("sweep", "LeRobot", "Universal Robots", "Datasets", "Kinematic identification"):
        assert any(system in h for h in headings), system


def test_every_module_is_on_the_map() -> None:
    """Every module of src/robocal (package ``__init__`` files aside) is a row of some system or the shared one."""
    on_map = set(_paths(_file_map()))
    modules = sorted(p.relative_to(SRC).as_posix() for p in SRC.rglob("*.py") if p.name != "__init__.py")
    assert [m for m in modules if m not in on_map] == [], "add these to the file map in docs/design.md"
