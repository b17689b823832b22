"""cli._common.print_warnings: one ``warning:`` line per warning on stderr, and the exit code they make."""

from __future__ import annotations

import pytest

from robocal.cli._common import EXIT_OK, EXIT_WARNINGS, print_warnings


def test_print_warnings_prints_each_on_stderr_and_returns_1(capsys: pytest.CaptureFixture[str]) -> None:
    assert print_warnings(("joint a beyond its range", "no .bak kept")) == EXIT_WARNINGS == 1
    out, err = capsys.readouterr()
    assert out == ""
    assert err == "warning: joint a beyond its range\nwarning: no .bak kept\n"


def test_print_warnings_without_warnings_prints_nothing_and_returns_0(
    capsys: pytest.CaptureFixture[str],
) -> None:
    assert print_warnings([]) == EXIT_OK == 0
    assert capsys.readouterr() == ("", "")


def test_parse_typed_assignments_converts_each_value_and_names_the_one_that_does_not() -> None:
    from robocal.cli._common import parse_typed_assignments
    from robocal.errors import UsageError

    assert parse_typed_assignments("a=-1, b = 1", "--sign", int, "expected -1 or 1") == {"a": -1, "b": 1}
    assert parse_typed_assignments(None, "--sign", int, "expected -1 or 1") == {}
    with pytest.raises(UsageError) as info:
        parse_typed_assignments("a=90,b=ninety", "--offset-deg", float, "expected a number of degrees")
    assert str(info.value) == "--offset-deg b=ninety: expected a number of degrees"
    with pytest.raises(UsageError, match=r"--sign 'a': expected name=value pairs"):
        parse_typed_assignments("a", "--sign", int, "expected -1 or 1")
