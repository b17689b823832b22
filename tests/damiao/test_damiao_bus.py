"""DamiaoBus against the simulated motors on python-can's virtual bus (real frames, real threads).

A third bus on the channel (:class:`Sniffer`) records every frame the host sends, so the bytes on the wire are
checked exactly; faults are judged by the simulated motor's state.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Iterator

import can
import pytest

from robocal.backends import load_backend
from robocal.backends.damiao.bus import LIMP, DamiaoBus, DamiaoMotor
from robocal.backends.damiao.faults import DamiaoLostCommError, DamiaoOverCurrentError
from robocal.backends.damiao.protocol import MitCommand
from robocal.backends.damiao.sim import SimDamiaoMotor
from robocal.backends.damiao.sim_bus import SimDamiaoBus
from robocal.backends.damiao.tables import Register, State
from robocal.core.vendors import vendor_spec
from robocal.errors import CalibTimeoutError, DeviceError, UsageError

_counter = itertools.count()
TIMEOUT_S = 5.0  # the simulator answers at once; 5 s only matters when a loaded machine holds this process up


class Sniffer:
    """Everything sent on the channel by the host (the simulator's replies go to MST_IDs 0x11+)."""

    def __init__(self, channel: str) -> None:
        self.bus = can.Bus(channel=channel, interface="virtual", receive_own_messages=False)

    def frames(self) -> list[tuple[int, str, bool]]:
        out = []
        while (msg := self.bus.recv(timeout=0.05)) is not None:
            if msg.arbitration_id < 0x10 or msg.arbitration_id == 0x7FF:
                out.append((msg.arbitration_id, bytes(msg.data).hex().upper(), bool(msg.is_fd)))
        return out


@pytest.fixture
def channel() -> str:
    return f"dm-bus-{next(_counter)}"


def _motors() -> list[SimDamiaoMotor]:
    return [
        SimDamiaoMotor(0x01, 0x11, "DM4310", mount_rad=2.0, zero_abs_rad=2.0, q_rad=0.3),
        SimDamiaoMotor(0x03, 0x13, "DM4340", registers={Register.VMAX: 8.0}),
    ]


SPECS = [DamiaoMotor("j1", 0x01, 0x11, "DM4310"), DamiaoMotor("j3", 0x03, 0x13, "DM4340")]


@pytest.fixture
def rig(channel: str) -> Iterator[tuple[list[SimDamiaoMotor], DamiaoBus, Sniffer]]:
    motors = _motors()
    with SimDamiaoBus(channel, motors):
        sniffer = Sniffer(channel)
        bus = DamiaoBus(channel, SPECS, interface="virtual", timeout_s=TIMEOUT_S, allow_motion=True)
        try:
            yield motors, bus, sniffer
        finally:
            bus.close()
            sniffer.bus.shutdown()


def test_registered_as_the_damiao_vendors_backend() -> None:
    assert load_backend("damiao") is DamiaoBus
    spec = vendor_spec("damiao")
    assert (spec.backend, spec.homing, spec.operating_mode_register, spec.live_can_sweep) == (
        "damiao",
        None,
        "CTRL_MODE",
        False,
    )


def test_connect_reads_each_motors_ranges_and_packs_with_them(
    rig: tuple[list[SimDamiaoMotor], DamiaoBus, Sniffer],
) -> None:
    motors, bus, sniffer = rig
    assert bus.range_sources == {"j1": "registers", "j3": "registers"}
    assert (bus.limits["j3"].p_max_rad, bus.limits["j3"].v_max_rad_s, bus.limits["j3"].t_max_nm) == (
        12.5,
        8.0,
        28.0,
    )
    sent = sniffer.frames()
    assert sent[:2] == [(0x7FF, "0100331500000000", False), (0x7FF, "0300331500000000", False)]
    assert [f[1][4:8] for f in sent] == ["3315", "3315", "3316", "3316", "3317", "3317"]
    bus.mit("j3", MitCommand(-math.pi / 2, 1.0, 45.0, 1.2, 2.0))
    assert sniffer.frames() == [
        (0x003, "6FE98FF1703D6891", False)
    ]  # VMAX 8: the motor's own, not the table's 10
    assert motors[1].last_command is not None
    assert motors[1].last_command.velocity_rad_s == pytest.approx(1.0, abs=0.004)


def test_ranges_from_the_table_send_nothing_and_say_so(
    channel: str, caplog: pytest.LogCaptureFixture
) -> None:
    with SimDamiaoBus(channel, _motors()):
        sniffer = Sniffer(channel)
        with DamiaoBus(channel, SPECS, interface="virtual", ranges="table", timeout_s=TIMEOUT_S) as bus:
            assert bus.range_sources == {"j1": "table", "j3": "table"}
            assert bus.limits["j3"].v_max_rad_s == 10.0
            assert sniffer.frames() == []
        sniffer.bus.shutdown()
    assert "ranges assumed from the model table, not read from j1, j3" in caplog.text


def test_refresh_reads_the_position_relative_to_the_stored_zero(
    rig: tuple[list[SimDamiaoMotor], DamiaoBus, Sniffer],
) -> None:
    motors, bus, sniffer = rig
    sniffer.frames()
    states = bus.refresh()
    assert states["j1"].position_rad == pytest.approx(0.3, abs=4e-4)
    assert (states["j1"].state, states["j1"].motor_id, states["j3"].motor_id) == (0, 1, 3)
    assert sniffer.frames() == [(0x7FF, "0100CC0000000000", False), (0x7FF, "0300CC0000000000", False)]
    assert motors[0].requests["refresh"] == 1


def test_read_only_by_default(channel: str) -> None:
    motors = _motors()
    with (
        SimDamiaoBus(channel, motors),
        DamiaoBus(channel, SPECS, interface="virtual", timeout_s=TIMEOUT_S) as bus,
    ):
        for call in (
            lambda: bus.enable(["j1"]),
            lambda: bus.mit("j1", MitCommand(0.0, 0.0, 10.0, 0.5, 0.0)),
            lambda: bus.write_register("j1", Register.TIMEOUT, 20),
            lambda: bus.set_zero("j1", confirm=True),
            lambda: bus.save("j1", confirm=True),
            lambda: bus.arm_watchdog("j1", 0.5),
        ):
            with pytest.raises(
                UsageError,
                match=r"motor 'j1' \(ESC_ID 0x1, MST_ID 0x11 on virtual:dm-bus-\d+\): .* "
                r"refused: the bus is read-only",
            ):
                call()
        assert bus.limp(["j1"])["j1"].torque_nm == pytest.approx(0.0, abs=0.003)
        bus.disable()
    assert motors[0].state == State.DISABLED and motors[0].flash_writes == 0
    assert motors[0].ram[Register.TIMEOUT] == 0.0
    assert set(motors[0].requests) == {"read", "mit", "disable"}


def test_set_zero_and_save_need_confirm_and_follow_openarm_cans_sequence(
    rig: tuple[list[SimDamiaoMotor], DamiaoBus, Sniffer],
) -> None:
    motors, bus, sniffer = rig
    with pytest.raises(UsageError, match="set zero writes the motor's flash; it needs confirm=True"):
        bus.set_zero("j1")
    with pytest.raises(UsageError, match="save writes the motor's flash; it needs confirm=True"):
        bus.save("j1")
    assert motors[0].flash_writes == 0
    sniffer.frames()
    state = bus.set_zero("j1", confirm=True)
    assert state.position_rad == pytest.approx(-1.907e-4, abs=1e-6)  # q 0 packs to 32767
    assert [f[:2] for f in sniffer.frames()] == [
        (0x001, "FFFFFFFFFFFFFFFD"),
        (0x001, "FFFFFFFFFFFFFFFE"),
        (0x001, "FFFFFFFFFFFFFFFD"),
        (0x7FF, "0100CC0000000000"),
    ]
    assert motors[0].zero_abs_rad == pytest.approx(2.3) and motors[0].flash_writes == 1
    bus.write_register("j1", Register.TIMEOUT, 40)
    bus.save("j1", confirm=True)
    assert motors[0].flash[Register.TIMEOUT] == 40.0 and motors[0].flash_writes == 2


def test_a_fault_raises_its_named_error_and_clear_error_clears_it(
    rig: tuple[list[SimDamiaoMotor], DamiaoBus, Sniffer],
) -> None:
    motors, bus, _ = rig
    bus.enable(["j1"])
    motors[0].inject_fault(State.OVER_CURRENT)
    with pytest.raises(
        DamiaoOverCurrentError, match=r"Damiao motor 'j1' \(ESC_ID 0x1.*reports over-current"
    ) as err:
        bus.refresh(["j1"])
    assert err.value.exit_code == 3
    assert bus.read_state("j1", check=False).state == State.OVER_CURRENT
    assert bus.clear_error("j1").state == State.DISABLED
    assert motors[0].state == State.DISABLED


def test_watchdog_trips_lost_comm(rig: tuple[list[SimDamiaoMotor], DamiaoBus, Sniffer]) -> None:
    motors, bus, sniffer = rig
    sniffer.frames()
    assert bus.arm_watchdog("j1", 0.001) == 0.0
    assert sniffer.frames() == [(0x7FF, "0100330900000000", False), (0x7FF, "0100550914000000", False)]
    bus.enable(["j1"])
    motors[0].last_rx_s = (motors[0].last_rx_s or 0.0) - 1.0  # the host was silent for a second
    with pytest.raises(DamiaoLostCommError, match="communication lost"):
        bus.refresh(["j1"])
    assert motors[0].state == State.LOST_COMM and len(motors[0].lost_comm_at_s) == 1
    bus.clear_error("j1")
    bus.disarm_watchdog("j1")
    assert motors[0].ram[Register.TIMEOUT] == 0.0


def test_writing_a_range_register_rescales_the_bus(
    rig: tuple[list[SimDamiaoMotor], DamiaoBus, Sniffer],
) -> None:
    motors, bus, _ = rig
    assert bus.write_register("j3", Register.VMAX, 10.0) == 10.0
    assert bus.limits["j3"].v_max_rad_s == 10.0 and motors[1].ram[Register.VMAX] == 10.0
    assert bus.write_register("j1", Register.KP_ASR, 0.1) == pytest.approx(0.1, abs=1e-8)  # float32 echo


def test_fd_bus_sends_commands_fd_and_register_frames_classic(channel: str) -> None:
    motors = _motors()
    with SimDamiaoBus(channel, motors):
        sniffer = Sniffer(channel)
        with DamiaoBus(
            channel, SPECS, interface="virtual", fd=True, timeout_s=TIMEOUT_S, allow_motion=True
        ) as bus:
            sniffer.frames()
            bus.enable(["j1"])
            bus.mit("j1", LIMP)
            bus.refresh(["j1"])
            bus.read_register("j1", Register.CTRL_MODE)
            assert sniffer.frames() == [
                (0x001, "FFFFFFFFFFFFFFFC", True),
                (0x001, "7FFF7FF0000007FF", True),
                (0x7FF, "0100CC0000000000", True),
                (0x7FF, "0100330A00000000", False),
            ]
        sniffer.bus.shutdown()


def test_a_silent_motor_is_named_in_the_timeout(channel: str) -> None:
    with SimDamiaoBus(channel, _motors(), silent=[0x03]):
        with pytest.raises(
            CalibTimeoutError, match=r"no reply within 0.2 s from motor 'j3' \(ESC_ID 0x3, MST_ID 0x13"
        ):
            DamiaoBus(channel, SPECS, interface="virtual", timeout_s=0.2)
        with DamiaoBus(channel, SPECS, interface="virtual", ranges="table", timeout_s=0.2) as bus:
            assert bus.probe() == {"j1"}


def test_bad_motor_lists_and_interfaces_are_refused() -> None:
    with pytest.raises(UsageError, match="repeats a name or an id"):
        DamiaoBus("x", [SPECS[0], DamiaoMotor("j2", 0x11, 0x21, "DM4310")], interface="virtual")
    with pytest.raises(UsageError, match=r"ESC_ID 0x7ff must be an 11-bit id below 0x7ff"):
        DamiaoBus("x", [DamiaoMotor("j", 0x7FF, 0x11, "DM4310")], interface="virtual")
    with pytest.raises(UsageError, match="unknown Damiao model 'DM9999'"):
        DamiaoBus("x", [DamiaoMotor("j", 1, 0x11, "DM9999")], interface="virtual")
    with pytest.raises(UsageError, match="CAN interface 'nope' is unknown to python-can"):
        DamiaoBus("x", SPECS, interface="nope")
    with pytest.raises(DeviceError, match="cannot open CAN socketcan:no-such-can"):
        DamiaoBus("no-such-can", SPECS, interface="socketcan")


def test_a_late_register_reply_is_not_taken_for_a_state_frame(
    rig: tuple[list[SimDamiaoMotor], DamiaoBus, Sniffer], monkeypatch: pytest.MonkeyPatch
) -> None:
    motors, bus, _ = rig
    answer = motors[0].handle

    def echo_first(arbitration_id: int, data: bytes) -> list[tuple[int, bytes]]:
        # an echo of an earlier register write reaches the host just before the refresh's state frame
        return [(0x11, bytes.fromhex("0100550914000000")), *answer(arbitration_id, data)]

    monkeypatch.setattr(motors[0], "handle", echo_first)
    state = bus.read_state("j1")
    assert state.position_rad == pytest.approx(
        0.3, abs=4e-4
    )  # not −12.5 rad (the echo read as a state frame)
    assert motors[0].requests["refresh"] == 1


def test_a_register_read_whose_reply_was_lost_once_is_asked_again(channel: str) -> None:
    """On a busy host one reply can come later than the wait; a read changes nothing, so it is asked again before
    the motor is named (the Damiao fault soaks lost runs at connect to "no reply within 0.1 s", issue 31)."""
    motors = _motors()
    real, dropped = motors[1].handle, []

    def handle(arbitration_id: int, data: bytes) -> list[tuple[int, bytes]]:
        out = real(arbitration_id, data)
        if arbitration_id == 0x7FF and data[2] == 0x33 and not dropped:
            dropped.append(data[3])  # the first register read it hears: its reply is lost
            return []
        return out

    motors[1].handle = handle  # type: ignore[method-assign]
    with SimDamiaoBus(channel, motors), DamiaoBus(channel, SPECS, interface="virtual", timeout_s=0.2) as bus:
        assert dropped == [Register.PMAX]  # the connect's first read (PMAX) went unanswered once
        assert bus.range_sources["j3"] == "registers" and bus.limits["j3"].v_max_rad_s == 8.0  # read, not assumed
