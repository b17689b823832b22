"""Make the fuzz helpers importable (``import fuzzlib``, ``import seeds``) in importlib mode."""

from __future__ import annotations

import sys
from pathlib import Path

_HERE = str(Path(__file__).parent)
if _HERE not in sys.path:
    sys.path.insert(0, _HERE)


def pytest_collection_modifyitems(items: list) -> None:  # type: ignore[type-arg]
    """Under the thorough profile a fuzz test runs ~100x the examples: lift the per-test timeout."""
    import os

    import pytest

    if os.environ.get("HYPOTHESIS_PROFILE") == "thorough":
        for item in items:
            if "fuzz" in item.nodeid:
                item.add_marker(pytest.mark.timeout(0))
