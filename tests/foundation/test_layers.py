"""The layering rules of CONTRIBUTING.md, checked."""

from __future__ import annotations

import ast
import re
import subprocess
import sys
from pathlib import Path

import pytest

SRC = Path(__file__).resolve().parents[2] / "src" / "robocal"
HEAVY = [
    "typer",
    "rich",
    "click",
    "can",
    "lxml",
    "ruamel",
    "pyarrow",
    "matplotlib",
    "scservo_sdk",
    "dynamixel_sdk",
    "serial",
    "rosbags",
    "scipy",
]


def test_core_imports_with_numpy_alone() -> None:
    modules = sorted(
        ".".join(p.relative_to(SRC / "core").with_suffix("").parts).removesuffix(".__init__")
        for p in (SRC / "core").rglob("*.py")
        if p.parent != SRC / "core" or p.stem != "__init__"
    )
    code = (
        "import sys\n"
        + "".join(f"import robocal.core.{m}\n" for m in modules)
        + f"heavy = [m for m in {HEAVY!r} if m in sys.modules]\n"
        + "print(','.join(heavy))\n"
    )
    out = subprocess.run(
        [sys.executable, "-c", code],
        capture_output=True,
        text=True,
        check=True,
        env={"PYTHONPATH": str(SRC.parent)},
    )
    assert out.stdout.strip() == "", f"robocal.core pulled in: {out.stdout.strip()}"
    assert "jointmap" in modules and "lerobot.normalisation" in modules


def _resolve(path: Path, node: ast.ImportFrom) -> str:
    """The absolute module an ``ImportFrom`` names (relative imports resolved against ``path``)."""
    if not node.level:
        return node.module or ""
    pkg = path.relative_to(SRC.parent).with_suffix("").parts
    base = list(pkg[: len(pkg) - node.level])
    return ".".join(base + ([node.module] if node.module else []))


def _robocal_imports(path: Path, text: str | None = None) -> set[str]:
    """Every ``robocal`` module ``path`` imports, at module level or lazily inside a function.

    ``from robocal import errors`` / ``from .. import errors`` count as importing ``robocal.errors``.
    """
    tree = ast.parse(path.read_text() if text is None else text)
    found: set[str] = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.ImportFrom):
            target = _resolve(path, node)
            if target == "robocal":
                found.update(f"robocal.{alias.name}" for alias in node.names)
            else:
                found.add(target)
        elif isinstance(node, ast.Import):
            found.update(alias.name for alias in node.names)
    return {t for t in found if t == "robocal" or t.startswith("robocal.")}


# Every package and top-level module under src/robocal, lowest first. A module may import from its own entry
# and from entries to its left, never from one to its right (that import would run back up).
LAYERS = [
    "errors",  # the exception tree
    "fileio",  # atomic writes, bounded reads
    "core",  # pure numpy
    "backends",  # hardware, recordings, simulators
    "formats",  # calibration files in and out
    "lerobot",  # the public LeRobot facade (normalisation, calibration paths, legacy files)
    "dataset",  # dataset recalibration engine
    "health",  # the public calibration-health facade (the live monitor; re-exports core.health)
    "workflows",  # one module per job
    "viewer",  # robocal view (viser page, feeds): built on workflows, called by the CLI
    "cli",  # typer commands
    "__main__",  # python -m robocal
]
_RANK = {name: i for i, name in enumerate(LAYERS)}


def _entry(path: Path) -> str:
    """The LAYERS entry of a file: its top-level package, or its module name for a top-level module."""
    return path.relative_to(SRC).parts[0].removesuffix(".py")


def _upward_imports() -> list[str]:
    violations = []
    for path in sorted(SRC.rglob("*.py")):
        if path == SRC / "__init__.py":
            continue  # the package root re-exports the public API (only robocal.errors today)
        own = _RANK[_entry(path)]
        for target in sorted(_robocal_imports(path)):
            parts = target.split(".")
            if len(parts) < 2 or parts[1] not in _RANK:
                continue  # importlib.metadata-style names are not robocal modules
            if _RANK[parts[1]] > own:
                violations.append(f"{path.relative_to(SRC).as_posix()} imports robocal.{parts[1]}")
    return violations


def test_every_package_has_a_layer() -> None:
    entries = {
        p.name.removesuffix(".py")
        for p in SRC.iterdir()
        if (p.is_dir() and (p / "__init__.py").exists()) or (p.suffix == ".py" and p.name != "__init__.py")
    }
    assert entries == set(LAYERS), "place each package of src/robocal in LAYERS"
    assert {"lerobot", "dataset"} <= entries


def test_root_package_imports_errors_only() -> None:
    assert _robocal_imports(SRC / "__init__.py") == {"robocal.errors"}


def test_imports_point_down_only() -> None:
    assert _upward_imports() == []


def _runtime_robocal_imports(path: Path) -> set[str]:
    """Like :func:`_robocal_imports`, without the imports under ``if TYPE_CHECKING:`` (annotations only)."""
    tree = ast.parse(path.read_text())
    for node in ast.walk(tree):
        if isinstance(node, ast.If) and ast.unparse(node.test) in ("TYPE_CHECKING", "typing.TYPE_CHECKING"):
            node.body = [ast.Pass()]
    return _robocal_imports(path, ast.unparse(tree))


# CLI modules that still import a backend at run time, with the helper moving that into a workflow. Only shrinks.
CLI_BACKEND_PENDING: dict[str, str] = {}


def test_cli_calls_workflows_not_backends() -> None:
    found = {
        path.relative_to(SRC).as_posix()
        for path in sorted((SRC / "cli").glob("*.py"))
        if any(t.startswith("robocal.backends") for t in _runtime_robocal_imports(path))
    }
    assert found - set(CLI_BACKEND_PENDING) == set()
    probe = SRC / "cli" / "_probe.py"
    text = "from typing import TYPE_CHECKING\nif TYPE_CHECKING:\n    from ..backends import sim\n"
    assert _robocal_imports(probe, text) == {"robocal.backends"}


def test_cli_reads_and_writes_files_through_workflows() -> None:
    """No CLI module reads or writes a file (or prints a file's text) through formats/, fileio/, dataset/ or the
    lerobot facade at run time: a workflow does (annotation-only imports under ``TYPE_CHECKING`` may stay)."""
    below = ("robocal.formats", "robocal.fileio", "robocal.dataset", "robocal.lerobot")
    found = {
        path.relative_to(SRC).as_posix()
        for path in sorted((SRC / "cli").glob("*.py"))
        if any(t == b or t.startswith(b + ".") for t in _runtime_robocal_imports(path) for b in below)
    }
    assert found == set()
    probe = SRC / "cli" / "_probe.py"
    text = "def f():\n    from ..formats.lerobot import dumps_current\n    from .. import fileio\n"
    assert _robocal_imports(probe, text) == {"robocal.formats.lerobot", "robocal.fileio"}


def _backend_classes_imported(path: Path, text: str | None = None) -> set[str]:
    """The registered backend classes (``BACKENDS``) ``path`` imports by name at run time."""
    from robocal.backends import BACKENDS

    registered = set(BACKENDS.values())
    tree = ast.parse(path.read_text() if text is None else text)
    for node in ast.walk(tree):
        if isinstance(node, ast.If) and ast.unparse(node.test) in ("TYPE_CHECKING", "typing.TYPE_CHECKING"):
            node.body = [ast.Pass()]
    return {
        f"{_resolve(path, node)}.{alias.name}"
        for node in ast.walk(tree)
        if isinstance(node, ast.ImportFrom)
        for alias in node.names
        if (_resolve(path, node), alias.name) in registered
    }


@pytest.mark.slow
def test_bus_and_client_classes_come_from_the_backend_registry() -> None:
    """Outside ``backends/``, a bus or client class is picked by ``load_backend(name)``, never imported."""
    found = {
        f"{path.relative_to(SRC).as_posix()}: {name}"
        for path in sorted(SRC.rglob("*.py"))
        if _entry(path) != "backends"
        for name in _backend_classes_imported(path)
    }
    assert found == set()
    probe = SRC / "viewer" / "_probe.py"
    text = "def f():\n    from ..backends.ur_primary import PrimaryClient, DEFAULT_PORT\n"
    assert _backend_classes_imported(probe, text) == {"robocal.backends.ur_primary.PrimaryClient"}


def test_the_checker_sees_an_upward_import() -> None:
    """The import walker finds lazy, relative and ``from .. import`` imports (so the check can fail)."""
    text = "import numpy\n\ndef f() -> None:\n    from ..workflows import sweep\n    from .. import cli\n"
    found = _robocal_imports(SRC / "core" / "_probe.py", text)
    assert found == {"robocal.workflows", "robocal.cli"}
    assert _entry(SRC / "core" / "_probe.py") == "core"


# --- one job per module, one meaning per class name (issue 16) ---------------------------------------------

MAX_LINES = 500

# Modules still over MAX_LINES, each with the helper splitting it. This list only shrinks.
OVERSIZE_PENDING: dict[str, str] = {}

# Class names still defined in more than one module, with the helper renaming them. This list only shrinks.
DUPLICATE_CLASS_PENDING: dict[str, str] = {}


def _line_counts() -> dict[str, int]:
    return {p.relative_to(SRC).as_posix(): len(p.read_text().splitlines()) for p in sorted(SRC.rglob("*.py"))}


def _class_definitions() -> dict[str, list[str]]:
    found: dict[str, list[str]] = {}
    for path in sorted(SRC.rglob("*.py")):
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.ClassDef):
                found.setdefault(node.name, []).append(path.relative_to(SRC).as_posix())
    return found


def test_no_module_over_500_lines() -> None:
    counts = _line_counts()
    over = {name: n for name, n in counts.items() if n > MAX_LINES and name not in OVERSIZE_PENDING}
    assert over == {}, f"split these by job (at most {MAX_LINES} lines each)"
    assert counts["errors.py"] < MAX_LINES  # the walk sees the top-level modules


def test_no_class_name_defined_twice() -> None:
    defined = _class_definitions()
    twice = {name: where for name, where in defined.items() if len(where) > 1}
    assert set(twice) - set(DUPLICATE_CLASS_PENDING) == set(), twice
    assert "CalibError" in defined  # the walk sees the classes


def test_issue16_nothing_pending() -> None:
    """Every module is under the size limit, every class name unique, no CLI module imports a backend."""
    assert (OVERSIZE_PENDING, DUPLICATE_CLASS_PENDING, CLI_BACKEND_PENDING) == ({}, {}, {})


REVIEW_WORDS = re.compile(r"audit|review|hardening|gaps|fixes|round\d|pass\d|_v\d")


def test_test_files_are_named_for_what_they_test() -> None:
    """A test file is named after the module or behaviour it tests, never after the review pass that wrote it."""
    tests = SRC.parents[1] / "tests"
    named = sorted(
        p.relative_to(tests).as_posix() for p in tests.rglob("test_*.py") if REVIEW_WORDS.search(p.stem)
    )
    assert named == []
    assert REVIEW_WORDS.search("test_sweep_review2") and REVIEW_WORDS.search("test_bad_input_audit")
