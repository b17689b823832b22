"""``workflows/`` is a handful of system folders: each says its job, none imports in a circle (issue 28)."""

from __future__ import annotations

import ast
from pathlib import Path

SRC = Path(__file__).resolve().parents[2] / "src" / "robocal"
WORKFLOWS = SRC / "workflows"
SHARED_MODULES = {"__init__.py", "written.py"}
SEED_SYSTEMS = {"autocal", "dataset", "demo", "files", "kinematics", "lerobot", "motion", "sim", "sweep", "ur"}
SYSTEMS = {p.name for p in WORKFLOWS.iterdir() if (p / "__init__.py").is_file()}
"""Every package under ``workflows/`` is a system (a new one needs only its folder and docstring)."""


def _imports(path: Path, *, top_level_only: bool) -> list[str]:
    """Absolute modules ``path`` imports (relative imports resolved; ``from X import m`` counts ``X.m`` too)."""
    tree = ast.parse(path.read_text(encoding="utf-8"))
    pkg = path.relative_to(SRC.parent).with_suffix("").parts
    nodes = tree.body if top_level_only else list(ast.walk(tree))
    found: list[str] = []
    for node in nodes:
        if isinstance(node, ast.ImportFrom):
            base = list(pkg[: len(pkg) - node.level]) if node.level else []
            module = ".".join(base + ([node.module] if node.module else []))
            found.append(module)
            found.extend(f"{module}.{alias.name}" for alias in node.names)
        elif isinstance(node, ast.Import):
            found.extend(alias.name for alias in node.names)
    return found


def _module_name(path: Path) -> str:
    return ".".join(path.relative_to(SRC.parent).with_suffix("").parts).removesuffix(".__init__")


def _system(module: str) -> str | None:
    parts = module.split(".")
    if parts[:2] != ["robocal", "workflows"] or len(parts) < 3:
        return None
    return parts[2] if parts[2] in SYSTEMS else None


def _cycle(graph: dict[str, set[str]]) -> list[str]:
    """One cycle of ``graph`` as a path, or ``[]``."""
    state: dict[str, int] = {}
    stack: list[str] = []

    def visit(node: str) -> list[str]:
        state[node] = 1
        stack.append(node)
        for nxt in sorted(graph.get(node, ())):
            if state.get(nxt) == 1:
                return [*stack[stack.index(nxt) :], nxt]
            if nxt not in state and (found := visit(nxt)):
                return found
        stack.pop()
        state[node] = 2
        return []

    for node in sorted(graph):
        if node not in state and (found := visit(node)):
            return found
    return []


def test_workflows_is_system_folders_each_with_a_docstring() -> None:
    loose = sorted(p.name for p in WORKFLOWS.glob("*.py") if p.name not in SHARED_MODULES)
    assert loose == [], f"modules outside a system folder: {loose}"
    folders = {p.name for p in WORKFLOWS.iterdir() if p.is_dir() and p.name != "__pycache__"}
    assert folders == SYSTEMS and SEED_SYSTEMS <= SYSTEMS  # no folder without __init__.py
    for name in sorted(folders):
        init = WORKFLOWS / name / "__init__.py"
        doc = ast.get_docstring(ast.parse(init.read_text(encoding="utf-8")))
        assert doc and len(doc) > 40, f"workflows/{name}/__init__.py needs a docstring saying its job"


def test_no_import_circle_between_systems() -> None:
    graph: dict[str, set[str]] = {}
    for path in WORKFLOWS.rglob("*.py"):
        here = _system(_module_name(path))
        if here is None:
            continue
        for module in _imports(path, top_level_only=False):
            there = _system(module)
            if there is not None and there != here:
                graph.setdefault(here, set()).add(there)
    assert _cycle(graph) == []
    assert "kinematics" not in graph.get("lerobot", set())  # the shipped simulated arms live in backends/sim


def test_no_import_circle_between_modules() -> None:
    modules = {_module_name(p): p for p in WORKFLOWS.rglob("*.py")}
    graph = {
        name: {m for m in _imports(path, top_level_only=True) if m in modules and m != name}
        for name, path in modules.items()
    }
    # a package's __init__ re-exporting its own modules is not a circle
    for name in graph:
        graph[name] = {m for m in graph[name] if not (name.endswith(m.rsplit(".", 1)[0]) and m.startswith(name))}
    assert _cycle(graph) == []


def test_no_system_imports_another_systems_private_module() -> None:
    offences = []
    for path in WORKFLOWS.rglob("*.py"):
        here = _system(_module_name(path))
        for module in _imports(path, top_level_only=False):
            there = _system(module)
            if there is not None and there != here and any(p.startswith("_") for p in module.split(".")[3:]):
                offences.append(f"{path.relative_to(SRC)} imports {module}")
    assert offences == []


def test_cycle_finder_finds_a_circle() -> None:
    assert _cycle({"a": {"b"}, "b": {"c"}, "c": {"a"}}) == ["a", "b", "c", "a"]
    assert _cycle({"a": {"b"}, "b": set()}) == []
