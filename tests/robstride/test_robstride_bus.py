"""RobstrideBus against the simulated motor on python-can's virtual bus (real frames, real threads)."""

from __future__ import annotations

import itertools
import math
import types
from collections.abc import Iterator

import can
import pytest

from robocal.backends import load_backend
from robocal.backends.robstride import MotorSpec, RobstrideBus
from robocal.backends.robstride import bus as bus_module
from robocal.backends.robstride.protocol import (
    CommType,
    Feedback,
    Param,
    encode_feedback,
    model_limits,
    split_id,
)
from robocal.backends.robstride.sim import SimMotor, SimMotorBus
from robocal.errors import CalibTimeoutError, UsageError

_counter = itertools.count()


def channel() -> str:
    return f"rs-bus-test-{next(_counter)}"


@pytest.fixture
def rig() -> Iterator[tuple[SimMotor, RobstrideBus, SimMotorBus]]:
    ch = channel()
    motor = SimMotor(can_id=1, model="rs-00", factory_zero_rad=1.234, q_rad=0.0)
    sim = SimMotorBus(ch, [motor]).start()
    # the simulated motor answers at once; 5 s only matters when a loaded machine holds this process up
    bus = RobstrideBus(ch, [MotorSpec("j1", 1, "rs-00")], interface="virtual", timeout_s=5.0)
    try:
        yield motor, bus, sim
    finally:
        bus.close()
        sim.stop()


def test_registry_points_at_the_bus() -> None:
    assert load_backend("robstride") is RobstrideBus


def test_fake_motor_round_trip(rig: tuple[SimMotor, RobstrideBus, SimMotorBus]) -> None:
    motor, bus, _ = rig
    fb = bus.enable("j1")
    assert fb.mode == 2 and fb.motor_id == 1 and fb.host_id == 0xFD
    assert bus.read_position("j1") == pytest.approx(1.234, abs=1e-6)  # float32 mechPos
    assert bus.read_position("j1") == pytest.approx(1.2339999675750732, abs=0)
    assert motor.requests.get(CommType.SET_ZERO, 0) == 0
    bus.set_zero("j1", confirm=True)
    assert bus.read_position("j1") == 0.0
    assert bus.read_firmware_version("j1") == "0.0.3.6"


def test_extended_frame_round_trips_without_echo() -> None:
    ch = channel()
    a = can.Bus(channel=ch, interface="virtual", receive_own_messages=False)
    b = can.Bus(channel=ch, interface="virtual", receive_own_messages=False)
    try:
        a.send(can.Message(arbitration_id=0x0200FD01, data=bytes(8), is_extended_id=True))
        msg = b.recv(timeout=1.0)
        assert msg is not None and msg.arbitration_id == 0x0200FD01 and msg.is_extended_id
        assert a.recv(timeout=0.0) is None  # no echo of own frames
    finally:
        a.shutdown()
        b.shutdown()


def test_zero_torque_is_passive(rig: tuple[SimMotor, RobstrideBus, SimMotorBus]) -> None:
    motor, bus, _ = rig
    motor.set_position(0.3)
    out = bus.zero_torque()
    assert list(out) == ["j1"]
    assert out["j1"].position_rad == pytest.approx(1.534, abs=4e-4)
    assert out["j1"].torque_nm == pytest.approx(0.0, abs=1e-3)
    assert motor.last_command == pytest.approx((0.0, 0.0, 0.0, 0.0, 0.0), abs=1e-3)
    assert motor.mode == 0  # never enabled
    assert motor.requests.get(CommType.SET_ZERO, 0) == 0 and motor.requests.get(CommType.ENABLE, 0) == 0


def test_set_zero_and_save_need_confirmation(rig: tuple[SimMotor, RobstrideBus, SimMotorBus]) -> None:
    motor, bus, _ = rig
    with pytest.raises(
        UsageError, match=r"motor 'j1' \(CAN id 1 .*\): set-zero \(type 6\) needs an explicit"
    ):
        bus.set_zero("j1")
    with pytest.raises(UsageError, match="save"):
        bus.save("j1")
    bus.write_param("j1", Param.RUN_MODE, 1)
    with pytest.raises(UsageError, match="refused in PP mode"):
        bus.set_zero("j1", confirm=True)
    assert motor.requests.get(CommType.SET_ZERO, 0) == 0
    bus.save("j1", confirm=True)
    assert motor.requests[CommType.SAVE] == 1


def test_zero_sta_add_offset_and_power_on_wrap(rig: tuple[SimMotor, RobstrideBus, SimMotorBus]) -> None:
    motor, bus, _ = rig
    assert bus.read_zero_sta("j1") == 0
    assert bus.read_add_offset("j1") == 0.0
    motor.set_position(-1.5)  # continuous raw -0.266 -> after power-on in [0, 2pi): 6.017
    motor.power_on()
    assert bus.read_position("j1") == pytest.approx(-0.266 + 2 * math.pi, abs=1e-5)
    bus.write_param("j1", Param.ZERO_STA, 1)
    motor.power_on()
    assert bus.read_zero_sta("j1") == 1
    assert bus.read_position("j1") == pytest.approx(-0.266, abs=1e-5)
    assert motor.true_homing_offset_rad == pytest.approx(1.234)


def test_silent_motor_is_named_in_timeout() -> None:
    ch = channel()
    motors = [SimMotor(can_id=11), SimMotor(can_id=14)]
    with (
        SimMotorBus(ch, motors, silent={14}),
        RobstrideBus(
            ch,
            [MotorSpec("left_shoulder_pitch", 11, "rs-02"), MotorSpec("left_elbow_pitch", 14)],
            interface="virtual",
            timeout_s=1.0,  # the silent motor costs this; the other must answer within it, however loaded
        ) as bus,
    ):
        with pytest.raises(
            CalibTimeoutError, match=r"no reply within 1 s from motor 'left_elbow_pitch' \(CAN id 14"
        ):
            bus.zero_torque()
        assert bus.zero_torque(["left_shoulder_pitch"])["left_shoulder_pitch"].motor_id == 11


def test_bad_arguments() -> None:
    with pytest.raises(UsageError, match="CAN id 0 must be between 1 and 254"):
        RobstrideBus("x", [MotorSpec("a", 0)], interface="virtual")
    with pytest.raises(UsageError, match="listed twice"):
        RobstrideBus("x", [MotorSpec("a", 1), MotorSpec("b", 1)], interface="virtual")
    with pytest.raises(UsageError, match="timeout"):
        RobstrideBus("x", [], interface="virtual", timeout_s=0)
    with (
        RobstrideBus(channel(), [MotorSpec("a", 1)], interface="virtual") as bus,
        pytest.raises(UsageError, match="no motor named 'b'"),
    ):
        bus.enable("b")


def test_late_reply_of_a_descheduled_reader_is_taken(monkeypatch: pytest.MonkeyPatch) -> None:
    """On a loaded machine the reading process can be descheduled past its deadline while the reply arrives:
    the reply came in time and is taken (it used to be a timeout, which failed sweeps under load)."""
    ch = channel()
    peer = can.Bus(channel=ch, interface="virtual", receive_own_messages=False)
    calls = itertools.count()

    def monotonic() -> float:
        # call 0: the deadline, right after the request was sent; call 1: the reader wakes up 10 s late and
        # meanwhile the motor's reply arrived (sent here, before the clock is read)
        if next(calls) == 1:
            request = peer.recv(timeout=30.0)
            assert request is not None and split_id(request.arbitration_id)[0] == CommType.MIT
            fb = Feedback(7, 0xFD, 2, 0, 0.5, 0.0, 0.0, 25.0)
            arb, data = encode_feedback(fb, model_limits("rs-00"))
            peer.send(can.Message(arbitration_id=arb, data=data, is_extended_id=True))
            return 1010.0
        return 1000.0

    monkeypatch.setattr(bus_module, "time", types.SimpleNamespace(monotonic=monotonic))
    try:
        with RobstrideBus(ch, [MotorSpec("j7", 7, "rs-00")], interface="virtual", timeout_s=0.1) as bus:
            assert bus.zero_torque()["j7"].position_rad == pytest.approx(0.5, abs=1e-3)
            with pytest.raises(CalibTimeoutError, match=r"no reply within 0.1 s from motor 'j7'"):
                bus.zero_torque()  # no reply at all: still a timeout
    finally:
        peer.shutdown()


def test_reply_timeout_floor_from_the_environment(monkeypatch: pytest.MonkeyPatch) -> None:
    from robocal.backends import REPLY_TIMEOUT_ENV, reply_timeout_floor_s

    monkeypatch.setenv(REPLY_TIMEOUT_ENV, "2000")
    with RobstrideBus(channel(), [MotorSpec("a", 1)], interface="virtual", timeout_s=0.1) as bus:
        assert bus.timeout_s == 2.0  # raised to the floor
    with RobstrideBus(channel(), [MotorSpec("a", 1)], interface="virtual", timeout_s=5.0) as bus:
        assert bus.timeout_s == 5.0  # a longer timeout is kept
    monkeypatch.setenv(REPLY_TIMEOUT_ENV, " ")
    assert reply_timeout_floor_s() == 0.0
    for bad in ("2s", "-1", "nan", "600001"):
        monkeypatch.setenv(REPLY_TIMEOUT_ENV, bad)
        with pytest.raises(UsageError, match=rf"ROBOCAL_REPLY_TIMEOUT_MS='{bad}': expected a number of ms"):
            RobstrideBus(channel(), [MotorSpec("a", 1)], interface="virtual")
