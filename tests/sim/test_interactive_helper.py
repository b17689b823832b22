"""The test helper that answers a child's prompts: a child that exits early fails with its own output."""

from __future__ import annotations

import sys
from pathlib import Path

import pytest

from .conftest import Interactive


def test_typing_to_a_child_that_exited_reports_its_exit_and_output(tmp_path: Path) -> None:
    run = Interactive(
        [sys.executable, "-c", "import sys; print('error: the bus went away'); sys.exit(3)"], tmp_path
    )
    run.proc.wait(timeout=60)
    with pytest.raises(AssertionError, match=r"exited 3 before reading ''[\s\S]*error: the bus went away"):
        run.send()
