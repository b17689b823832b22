"""The layering rules of CONTRIBUTING.md, checked."""

from __future__ import annotations

import ast
import subprocess
import sys
from pathlib import Path

SRC = Path(__file__).resolve().parents[2] / "src" / "robocal"
LAYERS = ["core", "backends", "formats", "workflows", "cli"]  # imports point down (left) only
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


def _robocal_imports(path: Path) -> set[str]:
    tree = ast.parse(path.read_text())
    found: set[str] = set()
    pkg = path.relative_to(SRC.parent).with_suffix("").parts
    for node in ast.walk(tree):
        if isinstance(node, ast.ImportFrom):
            if node.level:
                base = list(pkg[: len(pkg) - node.level])
                target = ".".join(base + ([node.module] if node.module else []))
            else:
                target = node.module or ""
            found.add(target)
        elif isinstance(node, ast.Import):
            found.update(alias.name for alias in node.names)
    return {t for t in found if t.startswith("robocal")}


def test_imports_point_down_only() -> None:
    violations = []
    for i, layer in enumerate(LAYERS):
        above = LAYERS[i + 1 :]
        for path in (SRC / layer).rglob("*.py"):
            for target in _robocal_imports(path):
                parts = target.split(".")
                if len(parts) > 1 and parts[1] in above:
                    violations.append(f"{path.relative_to(SRC)} imports {target}")
    assert violations == []
