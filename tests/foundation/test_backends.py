from __future__ import annotations

import importlib
import sys
from typing import ClassVar

import pytest

from robocal.backends import BACKENDS, list_backends, load_backend, require
from robocal.errors import BackendNotAvailableError, UsageError


def test_registry_loads_every_builtin_backend() -> None:
    assert {"robstride", "feetech", "dynamixel", "ur_primary", "damiao"} <= set(list_backends())
    for name, (module, attr) in BACKENDS.items():
        found = load_backend(name)
        assert found is getattr(importlib.import_module(module), attr)
        if isinstance(found, type):  # a bus, client, driver or source class
            assert found.__name__ == attr and found.__module__.startswith(module)
    loop = load_backend("dynamixel.position_loop")  # a vendor's position-loop model (not a class)
    assert loop.factory_gains("xl330-m288") == (400, 0, 0)  # ROBOTIS e-Manual: Position P 400, I 0, D 0


def test_unknown_backend_lists_valid_names() -> None:
    with pytest.raises(UsageError, match=r"unknown backend 'nope'; valid: damiao, damiao\.joint_driver, damiao\.source, dynamixel, dynamixel\.joint_driver, dynamixel\.position_loop, feetech"):
        load_backend("nope")


def test_missing_optional_dependency_names_the_extra(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setitem(sys.modules, "can", None)  # makes "import can" fail like an absent package
    with pytest.raises(BackendNotAvailableError, match=r"pip install 'robocal\[robstride\]'"):
        require("can", "the Robstride CAN backend")
    monkeypatch.setitem(sys.modules, "scservo_sdk", None)
    with pytest.raises(BackendNotAvailableError, match=r"robocal\[feetech\]"):
        require("scservo_sdk", "the Feetech backend")


def test_missing_opencv_and_scipy_keep_their_own_messages(monkeypatch: pytest.MonkeyPatch) -> None:
    from robocal.backends.vision import _cv2
    from robocal.workflows.kinematics.fit import _least_squares

    monkeypatch.setitem(sys.modules, "cv2", None)
    with pytest.raises(BackendNotAvailableError) as err:
        _cv2()
    assert str(err.value) == (
        "camera targets need OpenCV: pip install 'robocal[vision]' (opencv-python-headless)"
    )
    monkeypatch.setitem(sys.modules, "scipy.optimize", None)
    with pytest.raises(BackendNotAvailableError) as err:
        _least_squares()
    assert str(err.value) == "kinematic identification needs scipy: pip install 'robocal[kinematics]'"


class _RecordingBus:
    """Stands in for a registered backend class: records how robocal constructed it."""

    made: ClassVar[list[tuple[str, str, tuple[str, ...]]]] = []

    def __init__(self, *args: object, **kwargs: object) -> None:
        channel = str(args[0])
        names = tuple(getattr(m, "name", "?") for m in args[1])  # type: ignore[attr-defined]
        self.made.append((channel, str(kwargs.get("interface", "")), names))
        self.motors = names

    def close(self) -> None:
        pass


def test_sources_and_workflows_pick_backends_through_the_registry(monkeypatch: pytest.MonkeyPatch) -> None:
    # re-point the registry: what robocal opens then is the registered class, not a hand-picked import
    import types

    from robocal.backends.sources import JointSpec, RobstrideSource, open_source
    from robocal.workflows.lerobot import open_bus, robot_spec

    fake = types.ModuleType("robocal_test_fake_backend")
    fake.Bus = _RecordingBus  # type: ignore[attr-defined]
    monkeypatch.setitem(sys.modules, "robocal_test_fake_backend", fake)
    for name in ("robstride", "feetech"):
        monkeypatch.setitem(BACKENDS, name, ("robocal_test_fake_backend", "Bus"))
    _RecordingBus.made.clear()
    src = open_source("can:virtual:chan0", [JointSpec("left_hip", can_id=11, model="rs-02")])
    assert isinstance(src, RobstrideSource) and isinstance(src.buses[0], _RecordingBus)
    assert _RecordingBus.made == [("chan0", "virtual", ("left_hip",))]
    bus = open_bus(robot_spec("so101_follower"), "/dev/ttyFAKE")
    assert isinstance(bus, _RecordingBus) and _RecordingBus.made[-1][0] == "/dev/ttyFAKE"
