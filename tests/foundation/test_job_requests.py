"""Jobs take one request, not the command line's flags one by one: no public workflow function over 8 parameters.

Issue 28 item 3: a job takes one frozen request value (validated once, where it is built) and returns one result;
the CLI builds the request from its options. A function or method whose name has no leading underscore, at the top
level of a module under ``src/robocal/workflows/`` or in a public class there, may take at most
:data:`MAX_PARAMETERS` parameters (``self`` / ``cls`` not counted; ``*args`` and ``**kwargs`` count one each).
"""

from __future__ import annotations

import ast
from pathlib import Path

SRC = Path(__file__).resolve().parents[2] / "src" / "robocal"
WORKFLOWS = SRC / "workflows"
MAX_PARAMETERS = 8


def _parameters(fn: ast.FunctionDef | ast.AsyncFunctionDef, *, method: bool) -> int:
    a = fn.args
    names = [*a.posonlyargs, *a.args, *a.kwonlyargs]
    count = len(names) + (a.vararg is not None) + (a.kwarg is not None)
    is_static = any(isinstance(d, ast.Name) and d.id == "staticmethod" for d in fn.decorator_list)
    return count - 1 if method and not is_static and names else count


def _too_long(source: str, where: str) -> list[str]:
    """``where:name (n)`` for every public function or method of ``source`` over :data:`MAX_PARAMETERS`."""
    found: list[str] = []
    for node in ast.parse(source).body:
        if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)) and not node.name.startswith("_"):
            if (n := _parameters(node, method=False)) > MAX_PARAMETERS:
                found.append(f"{where}:{node.name} ({n})")
        elif isinstance(node, ast.ClassDef) and not node.name.startswith("_"):
            methods = [i for i in node.body if isinstance(i, (ast.FunctionDef, ast.AsyncFunctionDef))]
            for item in methods:
                if not item.name.startswith("_") and (n := _parameters(item, method=True)) > MAX_PARAMETERS:
                    found.append(f"{where}:{node.name}.{item.name} ({n})")
    return found


def test_no_public_workflow_function_takes_more_than_eight_parameters() -> None:
    found: list[str] = []
    for path in sorted(WORKFLOWS.rglob("*.py")):
        found += _too_long(path.read_text(encoding="utf-8"), path.relative_to(SRC).as_posix())
    assert found == [], "take one request value instead of the flags one by one (issue 28 item 3)"


def test_the_check_can_fail() -> None:
    source = (
        "def job(a, b, c, d, e, f, g, h, *, i=0): ...\n"
        "def fine(a, b, c, d, e, f, g, h): ...\n"
        "def _private(a, b, c, d, e, f, g, h, i): ...\n"
        "class Runner:\n"
        "    def run(self, a, b, c, d, e, f, g, h): ...\n"
        "    def go(self, a, b, c, d, e, f, g, h, **more): ...\n"
        "    @staticmethod\n"
        "    def build(a, b, c, d, e, f, g, h, i): ...\n"
    )
    assert _too_long(source, "m.py") == ["m.py:job (9)", "m.py:Runner.go (9)", "m.py:Runner.build (9)"]
