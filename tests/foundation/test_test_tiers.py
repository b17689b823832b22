"""The fast tier (``pytest -m "not slow"``) covers every test module.

A test marked ``slow`` (per test, per class or with a module's ``pytestmark``) runs only in the full suite. Each
test module keeps at least one test that is not slow, so a quick check while working still touches every area.
The check reads the test files' syntax (no import, no collection): a ``slow`` mark is any decorator or
``pytestmark`` entry whose last name is ``slow`` (``pytest.mark.slow``, ``slow`` imported from somewhere).
"""

from __future__ import annotations

import ast
from pathlib import Path

TESTS = Path(__file__).resolve().parents[1]


def _is_slow_mark(node: ast.expr) -> bool:
    """``pytest.mark.slow``, ``pytest.mark.slow(...)``, or a bare name ``slow``."""
    if isinstance(node, ast.Call):
        node = node.func
    if isinstance(node, ast.Attribute):
        return node.attr == "slow"
    return isinstance(node, ast.Name) and node.id == "slow"


def _marks_slow(value: ast.expr) -> bool:
    """A ``pytestmark`` value (one mark or a list/tuple of marks) that includes ``slow``."""
    if isinstance(value, (ast.List, ast.Tuple)):
        return any(_is_slow_mark(e) for e in value.elts)
    return _is_slow_mark(value)


def _pytestmark_is_slow(body: list[ast.stmt]) -> bool:
    for stmt in body:
        if (
            isinstance(stmt, ast.Assign)
            and any(isinstance(t, ast.Name) and t.id == "pytestmark" for t in stmt.targets)
            and _marks_slow(stmt.value)
        ):
            return True
        if (
            isinstance(stmt, ast.AnnAssign)
            and isinstance(stmt.target, ast.Name)
            and stmt.target.id == "pytestmark"
            and stmt.value is not None
            and _marks_slow(stmt.value)
        ):
            return True
    return False


def fast_and_slow_tests(source: str) -> tuple[list[str], list[str]]:
    """The names of a module's tests that are not marked slow, and of those that are."""
    tree = ast.parse(source)
    module_slow = _pytestmark_is_slow(tree.body)
    fast: list[str] = []
    slow: list[str] = []

    def visit(body: list[ast.stmt], inherited_slow: bool, prefix: str) -> None:
        for stmt in body:
            if isinstance(stmt, (ast.FunctionDef, ast.AsyncFunctionDef)) and stmt.name.startswith("test"):
                is_slow = inherited_slow or any(_is_slow_mark(d) for d in stmt.decorator_list)
                (slow if is_slow else fast).append(prefix + stmt.name)
            elif isinstance(stmt, ast.ClassDef) and stmt.name.startswith("Test"):
                class_slow = (
                    inherited_slow
                    or any(_is_slow_mark(d) for d in stmt.decorator_list)
                    or _pytestmark_is_slow(stmt.body)
                )
                visit(stmt.body, class_slow, f"{stmt.name}::")

    visit(tree.body, module_slow, "")
    return fast, slow


def test_every_test_module_has_a_test_in_the_fast_tier() -> None:
    modules = sorted(TESTS.rglob("test_*.py"))
    assert len(modules) > 100  # the walk found the suite
    all_slow = []
    for path in modules:
        fast, slow = fast_and_slow_tests(path.read_text(encoding="utf-8"))
        if slow and not fast:
            all_slow.append(str(path.relative_to(TESTS.parent)))
    assert all_slow == [], (
        "every test of these modules is marked slow, so `pytest -m 'not slow'` skips the module; "
        "keep one quick representative unmarked"
    )


def test_the_check_can_fail() -> None:
    module_mark = (
        "import pytest\npytestmark = [pytest.mark.timeout(9), pytest.mark.slow]\ndef test_a(): pass\n"
    )
    assert fast_and_slow_tests(module_mark) == ([], ["test_a"])
    per_test = (
        "import pytest\n@pytest.mark.slow\ndef test_a(): pass\n"
        "class TestB:\n    pytestmark = pytest.mark.slow\n    def test_c(self): pass\n"
        "@pytest.mark.slow\nclass TestD:\n    def test_e(self): pass\n"
        "def test_f(): pass\ndef helper(): pass\n"
    )
    assert fast_and_slow_tests(per_test) == (["test_f"], ["test_a", "TestB::test_c", "TestD::test_e"])
