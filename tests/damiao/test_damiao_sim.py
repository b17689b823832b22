"""The simulated Damiao motor answering real frames on python-can's virtual bus: exact bytes both ways.

The host side here is a bare python-can bus sending the frames of docs/damiao.md by hand, so what is checked is
the simulator alone (its state is read directly; the bus is tested in test_damiao_bus.py).
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Iterator

import can
import pytest

from robocal.backends.damiao.protocol import MitCommand, encode_mit_command
from robocal.backends.damiao.sim import TIMEOUT_UNIT_S, SimDamiaoMotor, default_registers
from robocal.backends.damiao.sim_bus import SimDamiaoBus
from robocal.backends.damiao.tables import Register, State, model_limits
from robocal.backends.sim.physics import JointPlant, OverloadLatch, PlantParams, SimClock
from robocal.errors import DeviceError, UsageError

_counter = itertools.count()
WAIT_S = 10.0  # generous: the simulator thread answers at once unless the machine holds it up


class Wire:
    """A host on the channel sending raw frames and reading the replies."""

    def __init__(self, channel: str) -> None:
        self.bus = can.Bus(channel=channel, interface="virtual", receive_own_messages=False)

    def ask(self, arb: int, hex_data: str, *, fd: bool = False) -> can.Message:
        self.bus.send(
            can.Message(arbitration_id=arb, data=bytes.fromhex(hex_data), is_extended_id=False, is_fd=fd)
        )
        msg = self.bus.recv(timeout=WAIT_S)
        assert msg is not None, f"no reply to {arb:03X}#{hex_data}"
        return msg

    def tell(self, arb: int, hex_data: str) -> None:
        self.bus.send(can.Message(arbitration_id=arb, data=bytes.fromhex(hex_data), is_extended_id=False))

    def quiet(self) -> bool:
        return self.bus.recv(timeout=0.2) is None


@pytest.fixture
def rig() -> Iterator[tuple[SimDamiaoMotor, SimDamiaoBus, Wire]]:
    ch = f"dm-sim-{next(_counter)}"
    motor = SimDamiaoMotor(0x01, 0x11, "DM4310", mount_rad=1.0, zero_abs_rad=1.0)
    sim = SimDamiaoBus(ch, [motor]).start()
    wire = Wire(ch)
    try:
        yield motor, sim, wire
    finally:
        wire.bus.shutdown()
        sim.stop()


def test_register_defaults_are_the_models_and_the_openarm_ids() -> None:
    regs = default_registers("DM8009", 0x02, 0x12)
    assert (regs[Register.PMAX], regs[Register.VMAX], regs[Register.TMAX]) == (12.5, 45.0, 54.0)
    assert (
        regs[Register.ESC_ID],
        regs[Register.MST_ID],
        regs[Register.TIMEOUT],
        regs[Register.CTRL_MODE],
    ) == (
        2.0,
        18.0,
        0.0,
        1.0,
    )
    assert (regs[Register.GR], regs[Register.NPP]) == (9.0, 21.0)
    assert default_registers("dm4340", 3, 0x13)[Register.VMAX] == 10.0


def test_refresh_and_enable_answer_the_pinned_state_frames(
    rig: tuple[SimDamiaoMotor, SimDamiaoBus, Wire],
) -> None:
    motor, _, wire = rig
    reply = wire.ask(0x7FF, "0100CC0000000000")
    assert (reply.arbitration_id, bytes(reply.data).hex(" ").upper()) == (0x11, "01 7F FF 7F F7 FF 1E 1C")
    reply = wire.ask(0x001, "FFFFFFFFFFFFFFFC")
    assert (reply.arbitration_id, bytes(reply.data).hex(" ").upper()) == (0x11, "11 7F FF 7F F7 FF 1E 1C")
    assert motor.state == State.ENABLED and motor.requests == {"refresh": 1, "enable": 1}
    reply = wire.ask(0x001, "FFFFFFFFFFFFFFFD")
    assert bytes(reply.data)[0] == 0x01 and motor.state == State.DISABLED


def test_a_reply_keeps_the_frame_type_of_the_request(rig: tuple[SimDamiaoMotor, SimDamiaoBus, Wire]) -> None:
    _, _, wire = rig
    assert wire.ask(0x7FF, "0100CC0000000000", fd=True).is_fd
    assert not wire.ask(0x7FF, "0100CC0000000000").is_fd


def test_registers_read_write_echo_and_save(rig: tuple[SimDamiaoMotor, SimDamiaoBus, Wire]) -> None:
    motor, _, wire = rig
    reply = wire.ask(0x7FF, "0100331500000000")  # read PMAX
    assert (reply.arbitration_id, bytes(reply.data).hex().upper()) == (0x11, "0100331500004841")
    reply = wire.ask(0x7FF, "01005509C8000000")  # TIMEOUT = 200 (10 ms)
    assert bytes(reply.data).hex().upper() == "01005509C8000000"
    assert motor.ram[Register.TIMEOUT] == 200.0 and motor.flash[Register.TIMEOUT] == 0.0
    wire.tell(0x7FF, "0100AA0000000000")  # save: no reply
    assert wire.quiet()
    assert motor.flash[Register.TIMEOUT] == 200.0 and motor.flash_writes == 1
    reply = wire.ask(0x7FF, "0100551600000041")  # VMAX = 8.0 in RAM only
    assert bytes(reply.data).hex().upper() == "0100551600000041"
    motor.power_on()
    assert motor.ram[Register.VMAX] == 30.0 and motor.ram[Register.TIMEOUT] == 200.0


def test_read_only_and_unknown_registers_are_not_answered(
    rig: tuple[SimDamiaoMotor, SimDamiaoBus, Wire],
) -> None:
    motor, _, wire = rig
    wire.tell(0x7FF, "0100551400000000")  # GR is read-only
    wire.tell(0x7FF, "0100332500000000")  # 37 names no register
    assert wire.quiet()
    assert motor.ram[Register.GR] == 10.0 and motor.requests == {"write": 1}


def test_a_range_register_rescales_the_frames_at_once(rig: tuple[SimDamiaoMotor, SimDamiaoBus, Wire]) -> None:
    motor, _, wire = rig
    motor.set_position(-0.5)  # reads 1.0 + (-0.5) - 1.0 = -0.5 rad
    assert bytes(wire.ask(0x7FF, "0100CC0000000000").data)[1:3].hex() == "7ae0"  # trunc(12 / 25 * 65535)
    wire.ask(0x7FF, "0100551500002041")  # PMAX = 10.0
    assert (
        bytes(wire.ask(0x7FF, "0100CC0000000000").data)[1:3].hex() == "7999"
    )  # trunc(9.5 / 20 * 65535) = 31129


def test_set_zero_is_kept_in_flash_and_a_power_cycle_rereads_within_half_a_turn(
    rig: tuple[SimDamiaoMotor, SimDamiaoBus, Wire],
) -> None:
    motor, _, wire = rig
    motor.set_position(0.25)
    reply = wire.ask(0x001, "FFFFFFFFFFFFFFFE")
    assert bytes(reply.data)[1:3].hex() == "7fff"  # reads 0 (the cell below it) at once
    assert motor.flash_writes == 1 and motor.zero_abs_rad == pytest.approx(1.25)
    motor.set_position(0.25 + math.radians(200))
    assert motor.reading_rad() == pytest.approx(math.radians(200))
    motor.power_on()  # no 0xAA was sent: the zero survives, the turn count does not
    assert motor.reading_rad() == pytest.approx(math.radians(200) - math.tau)
    motor.set_position(0.25 + math.radians(170))  # the count goes on from the aliased branch
    assert motor.reading_rad() == pytest.approx(math.radians(170) - math.tau)
    motor.power_on()  # within half a turn now: read right again
    assert motor.reading_rad() == pytest.approx(math.radians(170))


def test_a_factory_zero_reads_within_half_a_turn_of_it() -> None:
    motor = SimDamiaoMotor(1, 0x11, mount_rad=0.3, zero_abs_rad=6.0, q_rad=0.0)
    assert motor.reading_rad() == pytest.approx(0.3 - 6.0 + math.tau)


def test_a_fault_latches_until_clear_error_and_blocks_enable(
    rig: tuple[SimDamiaoMotor, SimDamiaoBus, Wire],
) -> None:
    motor, _, wire = rig
    wire.ask(0x001, "FFFFFFFFFFFFFFFC")
    motor.inject_fault(State.OVER_CURRENT)
    assert bytes(wire.ask(0x7FF, "0100CC0000000000").data)[0] == 0xA1
    assert bytes(wire.ask(0x001, "FFFFFFFFFFFFFFFC").data)[0] == 0xA1  # enable ignored
    assert bytes(wire.ask(0x001, "FFFFFFFFFFFFFFFB").data)[0] == 0x01  # cleared: disabled
    assert motor.state == State.DISABLED and motor.requests["clear error"] == 1
    with pytest.raises(UsageError, match="ENABLED is not a fault"):
        motor.inject_fault(State.ENABLED)


def test_zero_and_clear_can_go_unanswered() -> None:
    motor = SimDamiaoMotor(1, 0x11, answers_zero_and_clear=False)
    assert motor.handle(0x001, bytes.fromhex("FFFFFFFFFFFFFFFE")) == []
    assert motor.handle(0x001, bytes.fromhex("FFFFFFFFFFFFFFFB")) == []
    assert motor.flash_writes == 1 and motor.requests == {"set zero": 1, "clear error": 1}


def test_mit_frames_need_mit_mode_and_other_modes_frames_are_ignored(
    rig: tuple[SimDamiaoMotor, SimDamiaoBus, Wire],
) -> None:
    motor, _, wire = rig
    wire.tell(0x101, "0000803F00000040")  # POS_VEL frame: not simulated
    wire.ask(0x7FF, "0100550A02000000")  # CTRL_MODE = 2
    wire.tell(0x001, "7FFF7FF0511997FF")  # an MIT frame, now ignored
    assert wire.quiet()
    assert motor.last_command is None and "mit" not in motor.requests


def _plant_motor(clock: SimClock, **kw: object) -> SimDamiaoMotor:
    params = PlantParams(inertia_kgm2=0.002, stop_lower_rad=-1.0, stop_upper_rad=1.0, counts_per_rev=16384)
    plant = JointPlant(params, q0_rad=0.0, overload=kw.pop("overload", None))  # type: ignore[arg-type]
    return SimDamiaoMotor(1, 0x11, "DM4310", plant=plant, clock=clock, zero_abs_rad=0.0, **kw)  # type: ignore[arg-type]


def test_timeout_expiry_reports_lost_comm_and_goes_limp() -> None:
    clock = SimClock()
    motor = _plant_motor(clock)
    motor.handle(0x7FF, bytes.fromhex("0100550914000000"))  # TIMEOUT 20 units = 1 ms
    motor.handle(0x001, bytes.fromhex("FFFFFFFFFFFFFFFC"))
    enabled_at = clock.now()
    motor.handle(0x001, bytes.fromhex("7FFF7FF0511997FF"))
    clock.advance(0.0005)
    assert motor.handle(0x7FF, bytes.fromhex("0100CC0000000000"))[0][1][0] == 0x11  # within 1 ms: enabled
    clock.advance(0.002)
    ((arb, data),) = motor.handle(0x7FF, bytes.fromhex("0100CC0000000000"))
    assert (arb, data[0]) == (0x11, 0xD1) and motor.state == State.LOST_COMM
    assert motor.lost_comm_at_s == [pytest.approx(enabled_at + 2 * 0.0002 + 0.0005 + 20 * TIMEOUT_UNIT_S)]
    assert motor.drive().tau_max_nm == 0.0


def test_the_plant_moves_under_the_mit_law_and_an_overload_latches_0xe() -> None:
    clock = SimClock()
    motor = _plant_motor(clock, overload=OverloadLatch(threshold_nm=5.0, protection_s=0.05))
    motor.handle(0x001, bytes.fromhex("FFFFFFFFFFFFFFFC"))
    # q 0.5 rad, kp 20, kd 0.5 (DM4310 ranges): moves toward 0.5
    _, data = encode_mit_command(1, MitCommand(0.5, 0.0, 20.0, 0.5, 0.0), model_limits("DM4310"))
    motor.handle(0x001, data)
    clock.advance(1.0)
    motor.sync()
    assert motor.plant is not None and motor.plant.q_rad == pytest.approx(0.5, abs=0.01)
    _, data = encode_mit_command(1, MitCommand(3.0, 0.0, 50.0, 0.5, 0.0), model_limits("DM4310"))
    motor.handle(0x001, data)  # into the stop at 1.0 with 7 N·m (the DM4310's peak): overload after 50 ms
    clock.advance(0.2)
    ((_, reply),) = motor.handle(0x7FF, bytes.fromhex("0100CC0000000000"))
    assert reply[0] == 0xE1 and motor.state == State.OVERLOAD and motor.plant.latched
    assert motor.plant.peak_tau_motor_nm == pytest.approx(7.0)
    motor.handle(0x001, bytes.fromhex("FFFFFFFFFFFFFFFB"))
    assert motor.state == State.DISABLED and not motor.plant.latched


def test_two_motors_with_one_esc_id_are_refused() -> None:
    with pytest.raises(DeviceError, match="two motors share an ESC_ID"):
        SimDamiaoBus("x", [SimDamiaoMotor(1, 0x11), SimDamiaoMotor(1, 0x12)])
    with pytest.raises(DeviceError, match="a plant needs a simulated clock"):
        SimDamiaoMotor(1, 0x11, plant=JointPlant(PlantParams()))
