"""Damiao frames: golden vectors (exact bytes both ways) and pack/unpack round trips of the pure protocol layer.

The byte vectors are the ones the host stacks' formula gives (LeRobot 0.6.1 and openarm_can pack identically);
docs/damiao.md lists them with their sources.
"""

from __future__ import annotations

import math

import pytest
from hypothesis import given
from hypothesis import strategies as st

from robocal.backends.damiao.faults import (
    FAULT_ERRORS,
    DamiaoFaultError,
    DamiaoLostCommError,
    DamiaoRotorOverTempError,
    DamiaoUnknownStateError,
    fault_error,
)
from robocal.backends.damiao.protocol import (
    MitCommand,
    MotorState,
    RegisterReply,
    check_state,
    clear_error_frame,
    command_id,
    decode_mit_command,
    decode_register_reply,
    decode_special,
    decode_state,
    disable_frame,
    enable_frame,
    encode_mit_command,
    encode_register_reply,
    encode_state,
    float_to_uint,
    pack_register_value,
    refresh_frame,
    register_read_frame,
    register_write_frame,
    save_frame,
    set_zero_frame,
    special_frame,
    uint_to_float,
    unpack_register_value,
)
from robocal.backends.damiao.tables import (
    KD_MAX,
    KP_MAX,
    MODELS,
    ControlMode,
    MotorLimits,
    Register,
    State,
)
from robocal.errors import CalibError, DeviceError, ProtocolError, UsageError

DM4310 = MODELS["DM4310"]
DM8009 = MODELS["DM8009"]
DM4340_LR = MotorLimits("DM4340", 12.5, 8.0, 28.0, "LeRobot 0.6.1 table")


def _hex(data: bytes) -> str:
    return data.hex(" ").upper()


# ------------------------------------------------------------------------------------------ MIT golden vectors
MIT_VECTORS = [
    (DM4310, MitCommand(0.0, 0.0, 10.0, 0.5, 0.0), (32767, 2047, 81, 409, 2047), "7F FF 7F F0 51 19 97 FF"),
    (DM4310, MitCommand(0.0, 0.0, 0.0, 0.0, 0.0), (32767, 2047, 0, 0, 2047), "7F FF 7F F0 00 00 07 FF"),
    (
        DM8009,
        MitCommand(1.0, 0.0, 240.0, 5.0, 0.0),
        (35388, 2047, 1965, 4095, 2047),
        "8A 3C 7F F7 AD FF F7 FF",
    ),
    (
        DM4340_LR,
        MitCommand(-math.pi / 2, 1.0, 45.0, 1.2, 2.0),
        (28649, 2303, 368, 982, 2193),
        "6F E9 8F F1 70 3D 68 91",
    ),
    (
        MODELS["DM4340"],
        MitCommand(-math.pi / 2, 1.0, 45.0, 1.2, 2.0),
        (28649, 2252, 368, 982, 2193),
        "6F E9 8C C1 70 3D 68 91",
    ),
]


@pytest.mark.parametrize(("limits", "cmd", "raw", "expected"), MIT_VECTORS)
def test_mit_command_packs_to_the_reference_bytes(
    limits: MotorLimits, cmd: MitCommand, raw: tuple[int, ...], expected: str
) -> None:
    arb, data = encode_mit_command(1, cmd, limits)
    assert arb == 0x001
    assert _hex(data) == expected
    bits = int.from_bytes(data, "big")
    assert (bits >> 48, (bits >> 36) & 0xFFF, (bits >> 24) & 0xFFF, (bits >> 12) & 0xFFF, bits & 0xFFF) == raw


@pytest.mark.parametrize(("limits", "cmd", "raw", "expected"), MIT_VECTORS)
def test_mit_command_bytes_unpack_to_the_reference_fields(
    limits: MotorLimits, cmd: MitCommand, raw: tuple[int, ...], expected: str
) -> None:
    back = decode_mit_command(bytes.fromhex(expected), limits)
    q, dq, kp, kd, tau = raw
    assert back.position_rad == uint_to_float(q, -12.5, 12.5, 16)
    assert back.velocity_rad_s == uint_to_float(dq, -limits.v_max_rad_s, limits.v_max_rad_s, 12)
    assert back.kp == pytest.approx(kp * KP_MAX / 4095, abs=1e-12)
    assert back.kd == pytest.approx(kd * KD_MAX / 4095, abs=1e-12)
    assert back.torque_nm == uint_to_float(tau, -limits.t_max_nm, limits.t_max_nm, 12)
    assert abs(back.position_rad - cmd.position_rad) <= 25.0 / 65535


def test_zero_is_not_representable_and_decodes_half_a_step_low() -> None:
    _, data = encode_mit_command(1, MitCommand(0.0, 0.0, 0.0, 0.0, 0.0), DM4310)
    q = decode_mit_command(data, DM4310).position_rad
    assert q == pytest.approx(-1.907e-4, abs=1e-7)
    assert uint_to_float(32767, -12.5, 12.5, 16, centred=True) == pytest.approx(0.0, abs=1e-12)


def test_mit_fields_clamp_at_their_range_ends() -> None:
    over = MitCommand(100.0, 1e3, 1e4, 50.0, 1e3)
    under = MitCommand(-100.0, -1e3, -5.0, -1.0, -1e3)
    assert _hex(encode_mit_command(2, over, DM4310)[1]) == "FF FF FF FF FF FF FF FF"
    assert _hex(encode_mit_command(2, under, DM4310)[1]) == "00 00 00 00 00 00 00 00"


@pytest.mark.parametrize("bad", [math.nan, math.inf, -math.inf])
def test_a_non_finite_mit_field_is_refused(bad: float) -> None:
    with pytest.raises(UsageError, match="finite"):
        encode_mit_command(1, MitCommand(0.0, 0.0, bad, 0.0, 0.0), DM4310)


def _within(x: float, lo: float, hi: float, bits: int, back: float) -> bool:
    step = (hi - lo) / ((1 << bits) - 1)
    expected = min(max(x, lo), hi)
    return expected - step - 1e-9 <= back <= expected + 1e-9


finite = st.floats(allow_nan=False, allow_infinity=False, min_value=-1e6, max_value=1e6)


@given(
    model=st.sampled_from(sorted(MODELS)),
    q=finite,
    dq=finite,
    kp=st.floats(min_value=-10.0, max_value=600.0),
    kd=st.floats(min_value=-1.0, max_value=6.0),
    tau=finite,
)
def test_mit_round_trip_is_within_one_step_below_the_clamped_value(
    model: str, q: float, dq: float, kp: float, kd: float, tau: float
) -> None:
    lim = MODELS[model]
    back = decode_mit_command(encode_mit_command(3, MitCommand(q, dq, kp, kd, tau), lim)[1], lim)
    assert _within(q, -lim.p_max_rad, lim.p_max_rad, 16, back.position_rad)
    assert _within(dq, -lim.v_max_rad_s, lim.v_max_rad_s, 12, back.velocity_rad_s)
    assert _within(kp, 0.0, KP_MAX, 12, back.kp)
    assert _within(kd, 0.0, KD_MAX, 12, back.kd)
    assert _within(tau, -lim.t_max_nm, lim.t_max_nm, 12, back.torque_nm)


@given(u=st.integers(0, 0xFFF), bits=st.sampled_from([12, 16]))
def test_every_code_decodes_and_encodes_back_to_itself(u: int, bits: int) -> None:
    u &= (1 << bits) - 1
    assert float_to_uint(uint_to_float(u, -12.5, 12.5, bits, centred=True), -12.5, 12.5, bits) == u


# ---------------------------------------------------------------------------------------- state golden vectors
STATE_VECTORS = [
    (DM4310, "11 7F FF 7F F7 FF 1E 1C", 1, State.ENABLED, -1.907e-4, -0.00733, -0.00244, 30, 28),
    (DM8009, "12 8A 3C 80 07 FF 28 23", 2, State.ENABLED, 0.99966, 0.01099, -0.01319, 40, 35),
    (DM4310, "D5 80 00 7F F8 00 20 1F", 5, State.LOST_COMM, 1.907e-4, -0.00733, 0.00244, 32, 31),
]


@pytest.mark.parametrize(
    ("limits", "hexdata", "mid", "code", "q", "dq", "tau", "tmos", "trot"), STATE_VECTORS
)
def test_state_frame_unpacks_to_the_reference_values(
    limits: MotorLimits,
    hexdata: str,
    mid: int,
    code: State,
    q: float,
    dq: float,
    tau: float,
    tmos: int,
    trot: int,
) -> None:
    s = decode_state(bytes.fromhex(hexdata), limits)
    assert (s.motor_id, s.state, s.mos_temp_c, s.rotor_temp_c) == (mid, code, tmos, trot)
    assert s.position_rad == pytest.approx(q, rel=2e-3)
    assert s.velocity_rad_s == pytest.approx(dq, rel=2e-3)
    assert s.torque_nm == pytest.approx(tau, rel=3e-3)


@pytest.mark.parametrize(
    ("limits", "hexdata", "mid", "code", "q", "dq", "tau", "tmos", "trot"), STATE_VECTORS
)
def test_state_values_pack_to_the_reference_bytes(
    limits: MotorLimits,
    hexdata: str,
    mid: int,
    code: State,
    q: float,
    dq: float,
    tau: float,
    tmos: int,
    trot: int,
) -> None:
    decoded = decode_state(bytes.fromhex(hexdata), limits, centred=True)
    assert _hex(encode_state(decoded, limits)) == hexdata


@given(
    model=st.sampled_from(sorted(MODELS)),
    mid=st.integers(0, 15),
    code=st.sampled_from(list(State)),
    q=finite,
    dq=finite,
    tau=finite,
    tmos=st.integers(0, 255),
    trot=st.integers(0, 255),
)
def test_state_round_trip_is_within_one_step(
    model: str, mid: int, code: State, q: float, dq: float, tau: float, tmos: int, trot: int
) -> None:
    lim = MODELS[model]
    back = decode_state(encode_state(MotorState(mid, code, q, dq, tau, tmos, trot), lim), lim)
    assert (back.motor_id, back.state, back.mos_temp_c, back.rotor_temp_c) == (mid, code, tmos, trot)
    assert _within(q, -lim.p_max_rad, lim.p_max_rad, 16, back.position_rad)
    assert _within(dq, -lim.v_max_rad_s, lim.v_max_rad_s, 12, back.velocity_rad_s)
    assert _within(tau, -lim.t_max_nm, lim.t_max_nm, 12, back.torque_nm)


def test_a_short_state_frame_is_a_protocol_error() -> None:
    with pytest.raises(ProtocolError, match="7 bytes; expected 8"):
        decode_state(bytes(7), DM4310)


def test_state_fields_that_do_not_fit_are_refused() -> None:
    with pytest.raises(UsageError, match="4 bits"):
        encode_state(MotorState(16, 1, 0.0, 0.0, 0.0, 20, 20), DM4310)
    with pytest.raises(UsageError, match=r"0\.\.255"):
        encode_state(MotorState(1, 1, 0.0, 0.0, 0.0, 256, 20), DM4310)


# --------------------------------------------------------------------------------------------- special frames
@pytest.mark.parametrize(
    ("make", "expected"),
    [
        (enable_frame, "FF FF FF FF FF FF FF FC"),
        (disable_frame, "FF FF FF FF FF FF FF FD"),
        (set_zero_frame, "FF FF FF FF FF FF FF FE"),
        (clear_error_frame, "FF FF FF FF FF FF FF FB"),
    ],
)
def test_special_frames_are_the_reference_bytes(make: object, expected: str) -> None:
    arb, data = make(1)  # type: ignore[operator]
    assert (arb, _hex(data)) == (0x001, expected)
    assert decode_special(data) == data[7]


def test_an_mit_frame_or_unknown_command_is_not_a_special_frame() -> None:
    assert decode_special(encode_mit_command(1, MitCommand(0.0, 0.0, 10.0, 0.5, 0.0), DM4310)[1]) is None
    assert decode_special(bytes.fromhex("FFFFFFFFFFFFFFFA")) is None
    with pytest.raises(UsageError, match="special command 0xfa"):
        special_frame(1, 0xFA)


def test_ids_outside_eleven_bits_are_refused() -> None:
    with pytest.raises(UsageError, match="11-bit"):
        enable_frame(0x800)
    with pytest.raises(UsageError, match="POS_FORCE command id"):
        command_id(0x500, ControlMode.POS_FORCE)
    assert [command_id(0x05, m) for m in ControlMode] == [0x005, 0x105, 0x205, 0x305]


# ----------------------------------------------------------------------------------- refresh and registers
def test_refresh_frame_is_the_reference_bytes() -> None:
    arb, data = refresh_frame(8)
    assert (arb, _hex(data)) == (0x7FF, "08 00 CC 00 00 00 00 00")


@pytest.mark.parametrize(
    ("frame", "expected"),
    [
        (lambda: register_write_frame(0x01, Register.CTRL_MODE, 1), "01 00 55 0A 01 00 00 00"),
        (lambda: register_write_frame(0x01, Register.MST_ID, 0x11), "01 00 55 07 11 00 00 00"),
        (lambda: register_write_frame(0x03, Register.TIMEOUT, 0), "03 00 55 09 00 00 00 00"),
        (lambda: register_write_frame(0x05, Register.PMAX, 12.5), "05 00 55 15 00 00 48 41"),
        (lambda: register_read_frame(0x05, Register.PMAX), "05 00 33 15 00 00 00 00"),
        (lambda: save_frame(0x05), "05 00 AA 00 00 00 00 00"),
    ],
)
def test_register_frames_are_the_reference_bytes(frame: object, expected: str) -> None:
    arb, data = frame()  # type: ignore[operator]
    assert (arb, _hex(data)) == (0x7FF, expected)


def test_register_replies_round_trip_both_ops() -> None:
    for op, rid, value in ((0x33, Register.VMAX, 10.0), (0x55, Register.MST_ID, 17.0)):
        data = encode_register_reply(0x04, op, rid, value)
        assert decode_register_reply(data) == RegisterReply(0x04, op, rid, value)
    assert _hex(encode_register_reply(0x05, 0x33, Register.PMAX, 12.5)) == "05 00 33 15 00 00 48 41"


def test_a_register_reply_with_a_wrong_op_or_register_is_a_protocol_error() -> None:
    with pytest.raises(ProtocolError, match="op byte 0xcc"):
        decode_register_reply(bytes.fromhex("0500CC1500004841"))
    with pytest.raises(ProtocolError, match="unknown register 99"):
        decode_register_reply(bytes.fromhex("0500336300000000"))


def test_register_values_keep_their_type_and_refuse_what_does_not_fit() -> None:
    assert unpack_register_value(Register.TMAX, pack_register_value(Register.TMAX, 54.0)) == 54.0
    assert pack_register_value(Register.ESC_ID, 0x7FF) == bytes([0xFF, 0x07, 0, 0])
    with pytest.raises(UsageError, match="whole number"):
        pack_register_value(Register.ESC_ID, 1.5)
    with pytest.raises(UsageError, match="read-only"):
        register_write_frame(1, Register.GR, 10.0)
    with pytest.raises(UsageError, match="unknown Damiao register 99"):
        register_read_frame(1, 99)
    with pytest.raises(UsageError, match="finite"):
        pack_register_value(Register.PMAX, math.nan)


# ------------------------------------------------------------------------------------- state codes as errors
@pytest.mark.parametrize("code", [State.DISABLED, State.ENABLED])
def test_running_states_are_not_errors(code: State) -> None:
    state = MotorState(1, code, 0.0, 0.0, 0.0, 30, 30)
    assert fault_error(code, "joint_1") is None
    assert check_state(state, "joint_1") is state


@pytest.mark.parametrize("code", sorted(set(State) - {State.DISABLED, State.ENABLED}))
def test_every_error_state_raises_its_own_named_device_error(code: State) -> None:
    with pytest.raises(DamiaoFaultError) as info:
        check_state(MotorState(3, code, 0.0, 0.0, 0.0, 30, 30), "joint_3")
    err = info.value
    assert type(err) is FAULT_ERRORS[code] and err.state == code and err.motor == "joint_3"
    assert isinstance(err, DeviceError) and isinstance(err, CalibError) and err.exit_code == 3
    assert f"state {int(code):#x}" in str(err) and "joint_3" in str(err)


@pytest.mark.parametrize("code", [2, 3, 4, 5, 6, 7, 0xF])
def test_an_unnamed_state_is_a_protocol_error(code: int) -> None:
    err = fault_error(code, "gripper")
    assert isinstance(err, DamiaoUnknownStateError) and isinstance(err, ProtocolError)
    assert f"unknown state {code:#x}" in str(err)
    assert MotorState(8, code, 0.0, 0.0, 0.0, 0, 0).state_name == f"unknown state {code:#x}"


def test_the_reference_lost_comm_frame_raises_lost_comm() -> None:
    state = decode_state(bytes.fromhex("D580007FF800201F"), DM4310)
    assert state.state_name == "communication lost (TIMEOUT expired)"
    with pytest.raises(DamiaoLostCommError, match="joint_5 reports communication lost"):
        check_state(state, "joint_5")
    assert issubclass(DamiaoRotorOverTempError, DamiaoFaultError)
