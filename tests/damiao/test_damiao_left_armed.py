"""What a killed ``sweep --auto`` leaves armed on Damiao motors is kept in the state folder and put back by the next
run on that bus (issue 31, issue 26 item 2).

The TIMEOUT watchdog (register 9) lives in RAM: after SIGKILL it stays armed until a power cycle. The record is
written before the first TIMEOUT write, removed when the last one is put back; the next ``sweep --auto`` that opens
the bus says what it found (one ``note:``) and writes the values back. Judged by the simulated motors' registers
and the state folder's file.
"""

from __future__ import annotations

import json
import logging
from collections.abc import Iterator
from importlib import resources
from pathlib import Path

import pytest

pytest.importorskip("can")

from robocal.backends.damiao.openarm import SimOpenArm
from robocal.backends.damiao.tables import Register, State
from robocal.backends.sources.spec import parse_source
from robocal.formats.profiles import resolve_profile
from robocal.formats.urdf import read_urdf
from robocal.workflows.autocal.damiao import open_damiao
from robocal.workflows.motion.damiao_watchdog import WatchdogRecord, bus_key
from robocal.workflows.motion.snapshot import find_left_changed
from robocal.workflows.sweep.joint_specs import joints_from_urdf

GRIPPER = "openarm_right_gripper_motor"


@pytest.fixture
def arm(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Iterator[SimOpenArm]:
    monkeypatch.setenv("XDG_STATE_HOME", str(tmp_path / "state"))
    a = SimOpenArm(f"oa-left-armed-{id(tmp_path)}", side="right", seed=3).start()
    yield a
    a.stop()


def _open(arm: SimOpenArm) -> tuple[dict[str, object], object]:
    urdf_path = Path(str(resources.files("robocal").joinpath("data", "openarm_v10_right.urdf")))
    urdf = read_urdf(urdf_path)
    profile = resolve_profile("openarm_follower_right", urdf)
    assert profile is not None
    specs = joints_from_urdf(urdf, profile, None)
    drivers, _clock, close = open_damiao(parse_source(f"can:virtual:{arm.channel}"), specs, profile)
    return drivers, close  # type: ignore[return-value]


def test_a_killed_runs_armed_timeout_is_recorded_and_the_next_run_puts_it_back(
    arm: SimOpenArm, caplog: pytest.LogCaptureFixture
) -> None:
    key = bus_key("virtual", arm.channel)
    grip = arm.motors["gripper"]
    drivers, close = _open(arm)
    try:
        assert find_left_changed(key) is None
        assert drivers[GRIPPER].read().ok  # type: ignore[attr-defined]
        assert grip.enabled and grip.ram[Register.TIMEOUT] == 10000  # 0.5 s armed
        kept = find_left_changed(key)
        assert kept is not None and kept.registers == {GRIPPER: {"TIMEOUT": 0}}
        assert kept.command == "sweep --auto"
        # SIGKILL here: nothing more is sent; the motor's own watchdog makes it limp, TIMEOUT stays armed in RAM
    finally:
        close()  # type: ignore[operator]
    grip.state = State.DISABLED  # the watchdog made it limp (disabled); the register stays
    assert grip.ram[Register.TIMEOUT] == 10000 and Path(kept.path).is_file()

    with caplog.at_level(logging.INFO, logger="robocal.notes"):
        drivers, close = _open(arm)
    try:
        notes = [r.getMessage() for r in caplog.records if r.name == "robocal.notes"]
        assert len(notes) == 1
        assert f"left the host-loss watchdog (TIMEOUT) armed on {GRIPPER} (0.5 s); written back as before: {GRIPPER}" in notes[0]
        assert "a previous `robocal sweep --auto` (pid " in notes[0]
        assert grip.ram[Register.TIMEOUT] == 0 and find_left_changed(key) is None
        # this run records its own arming and removes the record once it put TIMEOUT back
        assert drivers[GRIPPER].read().ok  # type: ignore[attr-defined]
        assert json.loads(Path(kept.path).read_text())["registers"] == {GRIPPER: {"TIMEOUT": 0}}
        drivers[GRIPPER].limp()  # type: ignore[attr-defined]
        assert grip.ram[Register.TIMEOUT] == 0 and not grip.enabled and find_left_changed(key) is None
    finally:
        close()  # type: ignore[operator]


def test_the_record_keeps_the_first_value_per_motor_and_goes_when_the_last_is_back(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setenv("XDG_STATE_HOME", str(tmp_path / "state"))
    record = WatchdogRecord(bus_key("socketcand", "can0", {"host": "127.0.0.1", "port": 29536}))
    assert record.store.port == "damiao:socketcand:can0@127.0.0.1:29536"
    record.changed("j1", 0.0)
    record.changed("j2", 0.25)
    record.changed("j1", 0.5)  # armed again: the value before the run is kept
    kept = find_left_changed(record.store.port)
    assert kept is not None and kept.registers == {"j1": {"TIMEOUT": 0}, "j2": {"TIMEOUT": 5000}}
    record.changed("j1", None)
    kept = find_left_changed(record.store.port)
    assert kept is not None and kept.registers == {"j2": {"TIMEOUT": 5000}}
    record.changed("j2", None)
    assert find_left_changed(record.store.port) is None and not record.store.exists()


def test_a_timeout_write_whose_echo_is_lost_is_still_put_back_to_the_value_before(
    arm: SimOpenArm, monkeypatch: pytest.MonkeyPatch
) -> None:
    """The TIMEOUT write reaches the motor but its echo is lost: the driver must not read the armed value back as
    "the value before" (it put 0.5 s back and left the motor armed, seen in the fault soak)."""
    import math

    from robocal.backends.damiao.bus import DamiaoBus
    from robocal.backends.damiao.joint_driver import DamiaoJointDriver
    from robocal.errors import CalibTimeoutError

    grip = arm.motors["gripper"]
    with DamiaoBus(arm.channel, arm.motor_specs(), interface="virtual", allow_motion=True, timeout_s=1.0) as bus:
        real = bus.write_register
        lost: list[int] = []

        def echo_lost_once(motor: str, rid: int, value: float) -> float:
            out = real(motor, rid, value)  # the motor took it
            if not lost:
                lost.append(rid)
                raise CalibTimeoutError("no reply within 1 s (the echo was lost)")
            return out

        monkeypatch.setattr(bus, "write_register", echo_lost_once)
        d = DamiaoJointDriver(bus, "gripper", 1, 0.75, math.radians(3), arm.clock)
        assert not d.read().ok and lost == [Register.TIMEOUT]  # the enable did not happen
        assert grip.ram[Register.TIMEOUT] == 10000 and not grip.enabled  # yet the motor is armed
        assert d.read().ok and grip.enabled
        d.limp()
        assert grip.ram[Register.TIMEOUT] == 0 and not grip.enabled  # the value before robocal, not 0.5 s
