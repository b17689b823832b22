from __future__ import annotations

import sys

import pytest

from robocal.backends import BACKENDS, list_backends, load_backend, require
from robocal.errors import BackendNotAvailableError, UsageError


def test_registry_loads_every_builtin_backend() -> None:
    assert {"robstride", "feetech", "dynamixel", "ur_primary"} <= set(list_backends())
    for name, (module, attr) in BACKENDS.items():
        cls = load_backend(name)
        assert cls.__name__ == attr and cls.__module__.startswith(module)


def test_unknown_backend_lists_valid_names() -> None:
    with pytest.raises(UsageError, match="unknown backend 'nope'; valid: dynamixel, feetech"):
        load_backend("nope")


def test_missing_optional_dependency_names_the_extra(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setitem(sys.modules, "can", None)  # makes "import can" fail like an absent package
    with pytest.raises(BackendNotAvailableError, match=r"pip install 'robocal\[robstride\]'"):
        require("can", "the Robstride CAN backend")
    monkeypatch.setitem(sys.modules, "scservo_sdk", None)
    with pytest.raises(BackendNotAvailableError, match=r"robocal\[feetech\]"):
        require("scservo_sdk", "the Feetech backend")
