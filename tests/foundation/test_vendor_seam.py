"""A vendor is data plus one adapter: no code outside the vendor declarations compares vendor names.

Every vendor-dependent rule is a field of the vendor's :class:`~robocal.core.vendors.VendorSpec`; a comparison
such as ``spec.vendor == "feetech"`` (or ``in ("feetech", ...)``, ``match vendor: case "dynamixel"``) would let a
new vendor quietly take another vendor's branch, so this test forbids them everywhere but in the declarations.
"""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

from robocal.core.lerobot import RobotSpec, half_turn_homing_offset
from robocal.core.vendors import VENDORS, VendorSpec, vendor_spec
from robocal.errors import InvalidCalibrationError, UsageError
from robocal.workflows.autocal.model import joint_driver_class

SRC = Path(__file__).resolve().parents[2] / "src" / "robocal"
DECLARATIONS = {"core/vendors.py"}
"""Modules that may name vendors in comparisons (the declarations; they need none today)."""
NAMES = frozenset(VENDORS)


def _vendor_literals(node: ast.AST) -> list[str]:
    """Vendor names written as string constants in ``node`` (a constant, or a tuple/list/set of them)."""
    if isinstance(node, ast.Constant) and isinstance(node.value, str) and node.value in NAMES:
        return [node.value]
    if isinstance(node, ast.Tuple | ast.List | ast.Set):
        return [v for e in node.elts for v in _vendor_literals(e)]
    return []


def vendor_comparisons(source: str) -> list[tuple[int, str]]:
    """``(line, vendor)`` of every comparison or ``match`` case against a vendor-name literal."""
    found: list[tuple[int, str]] = []
    for node in ast.walk(ast.parse(source)):
        if isinstance(node, ast.Compare):
            for side in (node.left, *node.comparators):
                found += [(node.lineno, v) for v in _vendor_literals(side)]
        elif isinstance(node, ast.match_case):
            for sub in ast.walk(node.pattern):
                if isinstance(sub, ast.MatchValue):
                    found += [(sub.lineno, v) for v in _vendor_literals(sub.value)]
    return found


@pytest.mark.parametrize(
    "code",
    [
        'if spec.vendor == "feetech": pass',
        'x = 1 if vendor != "dynamixel" else 0',
        'ok = family in ("feetech", "dynamixel")',
        'ok = "robstride" == name',
        'match vendor:\n    case "dynamixel":\n        pass',
    ],
)
def test_the_check_sees_every_form_of_vendor_comparison(code: str) -> None:
    assert len(vendor_comparisons(code)) >= 1


def test_the_check_lets_lookups_and_other_strings_pass() -> None:
    code = 'spec = VENDORS["feetech"]\nif kind == "sim": pass\nbus = load_backend(spec.backend)\n'
    assert vendor_comparisons(code) == []


def test_no_code_outside_the_declarations_compares_vendor_names() -> None:
    offenders = []
    for path in sorted(SRC.rglob("*.py")):
        rel = path.relative_to(SRC).as_posix()
        if rel in DECLARATIONS:
            continue
        offenders += [f"{rel}:{line} compares with {v!r}" for line, v in vendor_comparisons(path.read_text())]
    assert offenders == [], "read the vendor's declaration (robocal.core.vendors) instead:\n" + "\n".join(offenders)


def test_every_vendor_is_declared_once_under_its_own_name() -> None:
    assert set(VENDORS) == {"feetech", "dynamixel", "robstride", "damiao"}
    for name, spec in VENDORS.items():
        assert isinstance(spec, VendorSpec) and spec.name == name
        assert vendor_spec(name) is spec


def test_the_declared_homing_rules_are_the_firmware_rules() -> None:
    feetech, dynamixel = VENDORS["feetech"].homing_rule(), VENDORS["dynamixel"].homing_rule()
    # Feetech: Present = Actual − Homing_Offset, sign-magnitude bit 11, wrapped per turn, drive mode in software
    assert (feetech.offset_sign, feetech.encoding, feetech.sign_bit, feetech.wraps_per_turn) == (
        -1,
        "sign-magnitude",
        11,
        True,
    )
    assert feetech.present(1000, 200) == 800 and feetech.offset_for_shift(10, 5) == 15
    assert not VENDORS["feetech"].drive_mode_in_hardware and VENDORS["feetech"].lock_register == "Lock"
    # Dynamixel: Present = Actual + Homing_Offset, two's complement, absolute, Drive_Mode in the motor
    assert (dynamixel.offset_sign, dynamixel.encoding, dynamixel.wraps_per_turn) == (1, "twos-complement", False)
    assert dynamixel.present(1000, 200) == 1200 and dynamixel.offset_for_shift(10, 5) == 5
    assert VENDORS["dynamixel"].drive_mode_in_hardware and VENDORS["dynamixel"].lock_register is None
    assert feetech.turn_shift(5000.0, 900, 4096) == 4096 and dynamixel.turn_shift(5000.0, 900, 4096) == 0
    with pytest.raises(UsageError, match="vendor 'robstride' has no Homing_Offset register"):
        VENDORS["robstride"].homing_rule()


def test_an_unknown_vendor_is_refused_not_given_another_vendors_rules() -> None:
    with pytest.raises(UsageError, match=r"unknown vendor 'kinova'; valid: damiao, dynamixel, feetech, robstride"):
        vendor_spec("kinova")
    with pytest.raises(InvalidCalibrationError, match=r"vendor 'kinova': expected 'feetech' or 'dynamixel'"):
        half_turn_homing_offset(1000, vendor="kinova")
    with pytest.raises(InvalidCalibrationError, match=r"vendor 'damiao': expected 'feetech' or 'dynamixel'"):
        half_turn_homing_offset(1000, vendor="damiao")  # declared, but no Homing_Offset register
    spec = RobotSpec("arm", "arm", "arm", "robots", "kinova", (), (), 3)
    with pytest.raises(UsageError, match="unknown vendor 'kinova'"):
        _ = spec.homing


def test_every_servo_vendor_has_each_of_its_adapters() -> None:
    """A vendor with a homing rule (a LeRobot servo vendor) is declared with all its adapters, not some."""
    from robocal.backends import BACKENDS
    from robocal.backends.sim.servo_model import SIM_SERVO_KINDS
    from robocal.workflows.lerobot.configure import _PRESETS

    servo_vendors = {n for n, v in VENDORS.items() if v.homing is not None}
    assert servo_vendors == {"feetech", "dynamixel"}
    for registry in (_PRESETS, SIM_SERVO_KINDS):
        assert set(registry) == servo_vendors
    assert {v.backend for v in VENDORS.values()} <= set(BACKENDS)
    drivers = {v.joint_driver for v in VENDORS.values() if v.joint_driver is not None}
    assert drivers <= set(BACKENDS)
    for name in servo_vendors:  # a servo vendor's stop search lives in its own home, found through load_backend
        driver = joint_driver_class(name)
        assert driver.__module__ == f"robocal.backends.{name}.joint_driver"


class _RecordingBus:
    """A bus that records writes (and has every register)."""

    def __init__(self) -> None:
        self.writes: list[tuple[str, int, int]] = []

    def write(self, register: str, motor_id: int, value: int) -> None:
        self.writes.append((register, motor_id, value))

    def has_register(self, motor_id: int, register: str) -> bool:
        return True


def test_lerobot_configure_refuses_an_undeclared_vendor_before_writing() -> None:
    from robocal.core.lerobot import LeRobotMotor
    from robocal.workflows.lerobot.configure import configure

    spec = RobotSpec("arm", "arm", "arm", "robots", "kinova", (LeRobotMotor("gripper", 1, "m", "range_0_100"),), (), 3)
    bus = _RecordingBus()
    with pytest.raises(UsageError, match="no LeRobot configure presets for vendor 'kinova'; valid: feetech, dynamixel"):
        configure(bus, spec)  # type: ignore[arg-type]
    assert bus.writes == []
