"""robocal.backends.feetech / .dynamixel: register widths, empty sync calls, the missing SDK's extra."""

from __future__ import annotations

from collections.abc import Iterator

import pytest

from robocal.backends.dynamixel import DynamixelBus
from robocal.backends.feetech import FeetechBus
from robocal.backends.sim.servo import SimServo, SimServoBus
from robocal.errors import UsageError

pytestmark = pytest.mark.timeout(60)


# ------------------------------------------------------------------------------------------------- buses
@pytest.fixture
def buses() -> Iterator[tuple[FeetechBus, DynamixelBus]]:
    with (
        SimServoBus([SimServo(1, "sts3215", 1337.0)]) as fsim,
        SimServoBus([SimServo(1, "xl330-m288", 1337.0)]) as dsim,
    ):
        fb = FeetechBus(fsim.port, {1: "sts3215"}, retries=0)
        db = DynamixelBus(dsim.port, {1: "xl330-m288"}, retries=0)
        try:
            yield fb, db
        finally:
            fb.close()
            db.close()


def test_sync_write_checks_the_register_width(buses: tuple[FeetechBus, DynamixelBus]) -> None:
    fb, db = buses
    with pytest.raises(UsageError, match="does not fit register 'Lock'"):
        fb.sync_write("Lock", {1: 256})
    with pytest.raises(UsageError, match="does not fit register 'Drive_Mode'"):
        db.sync_write("Drive_Mode", {1: 300})
    assert fb.ping(1) == 777 and db.ping(1) == 1200  # nothing was sent; the buses still work


def test_empty_sync_calls_are_usage_errors(buses: tuple[FeetechBus, DynamixelBus]) -> None:
    for bus in buses:
        with pytest.raises(UsageError, match="no motor ids"):
            bus.sync_read("Present_Position", [])
        with pytest.raises(UsageError, match="no motor ids"):
            bus.sync_write("Goal_Position", {})


@pytest.mark.parametrize(("module", "extra"), [("scservo_sdk", "feetech"), ("dynamixel_sdk", "dynamixel")])
def test_missing_sdk_names_the_extra(monkeypatch: pytest.MonkeyPatch, module: str, extra: str) -> None:
    import sys

    from robocal.errors import BackendNotAvailableError

    monkeypatch.setitem(sys.modules, module, None)
    bus_cls = FeetechBus if extra == "feetech" else DynamixelBus
    with pytest.raises(BackendNotAvailableError, match=rf"pip install 'robocal\[{extra}\]'"):
        bus_cls("/dev/null", {1: "sts3215" if extra == "feetech" else "xl330-m288"})
