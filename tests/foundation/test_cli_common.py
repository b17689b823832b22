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
