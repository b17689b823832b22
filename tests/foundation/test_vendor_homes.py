"""A vendor is one folder: what its declaration promises sits in ``backends/<name>/`` (issue 28 item 1)."""

from __future__ import annotations

from pathlib import Path

import pytest

from robocal.backends import BACKENDS, load_backend
from robocal.backends.sim.servo_model import SIM_SERVO_KINDS
from robocal.core.vendors import VENDORS

BACKENDS_DIR = Path(__file__).resolve().parents[2] / "src" / "robocal" / "backends"


@pytest.mark.parametrize("name", sorted(VENDORS))
def test_each_vendor_has_one_home_with_its_bus_tables_and_simulator(name: str) -> None:
    spec = VENDORS[name]
    home = BACKENDS_DIR / name
    assert (home / "__init__.py").is_file()
    for module in ("bus.py", "sim.py"):
        assert (home / module).is_file(), f"backends/{name}/{module}"
    assert (home / "tables.py").is_file() or (home / "protocol.py").is_file()
    module, _ = BACKENDS[spec.backend]
    assert module.startswith(f"robocal.backends.{name}")
    if spec.joint_driver is not None:
        assert (home / "joint_driver.py").is_file()
        driver = load_backend(spec.joint_driver)
        assert driver.__module__ == f"robocal.backends.{name}.joint_driver"


def test_servo_simulators_and_their_firmware_live_in_the_vendor_home() -> None:
    assert set(SIM_SERVO_KINDS) == {n for n, v in VENDORS.items() if v.homing is not None}
    for name, kind in SIM_SERVO_KINDS.items():
        assert kind.firmware.__module__ == f"robocal.backends.{name}.sim"


def test_no_vendor_code_left_in_the_shared_simulator_folder() -> None:
    shared = {p.stem for p in (BACKENDS_DIR / "sim").glob("*.py")}
    assert not shared & set(VENDORS), f"vendor modules in backends/sim/: {sorted(shared & set(VENDORS))}"
