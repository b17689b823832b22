"""robocal.lerobot is the public facade: re-exports only, and nothing below the CLI imports it."""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

import robocal.lerobot as facade
import robocal.lerobot.legacy as facade_legacy
from robocal.core.lerobot import legacy as core_legacy
from robocal.core.lerobot import normalisation
from robocal.formats import lerobot as formats_lerobot

SRC = Path(__file__).resolve().parents[2] / "src" / "robocal"


def _imports_facade(path: Path) -> bool:
    pkg = path.relative_to(SRC.parent).with_suffix("").parts
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.ImportFrom):
            base = list(pkg[: len(pkg) - node.level]) if node.level else []
            target = ".".join(base + ([node.module] if node.module else []))
            names = [target] + [f"{target}.{a.name}" for a in node.names]
        elif isinstance(node, ast.Import):
            names = [a.name for a in node.names]
        else:
            continue
        if any(n == "robocal.lerobot" or n.startswith("robocal.lerobot.") for n in names):
            return True
    return False


@pytest.mark.slow
def test_no_lower_layer_imports_the_facade() -> None:
    users = sorted(
        str(p.relative_to(SRC))
        for p in SRC.rglob("*.py")
        if p.parts[len(SRC.parts)] not in ("lerobot", "cli") and _imports_facade(p)
    )
    assert users == []


def test_the_facade_holds_no_code() -> None:
    for path in (SRC / "lerobot").glob("*.py"):
        tree = ast.parse(path.read_text())
        kinds = {type(node).__name__ for node in tree.body[1:]}  # after the docstring
        assert kinds <= {"ImportFrom", "Import", "Assign"}, (path.name, kinds)


def test_the_facade_names_are_the_lower_layers_objects() -> None:
    assert facade.NormMode is normalisation.NormMode
    assert facade.normalize is normalisation.normalize
    assert facade.read_calibration is formats_lerobot.read_current
    assert facade.write_calibration is formats_lerobot.write_current
    assert facade.calibration_path is formats_lerobot.calibration_path
    assert facade_legacy.apply_calibration is core_legacy.apply_calibration
    assert facade_legacy.to_robot_calibration is core_legacy.to_robot_calibration
    assert facade_legacy.read_legacy is formats_lerobot.read_legacy
