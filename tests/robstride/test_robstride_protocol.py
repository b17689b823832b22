"""Robstride private-protocol frames: golden vectors from the manual and the model table."""

from __future__ import annotations

import math
import struct

import pytest
from hypothesis import given
from hypothesis import strategies as st

from robocal.backends.robstride.protocol import (
    MODELS,
    P_MAX_RAD,
    CommType,
    Feedback,
    Param,
    decode_fault_report,
    decode_feedback,
    decode_firmware_reply,
    decode_mit_command,
    decode_param_reply,
    encode_feedback,
    encode_firmware_reply,
    encode_mit_command,
    encode_param_read,
    encode_param_reply,
    encode_param_write,
    float_to_uint,
    float_to_uint_7fff,
    make_id,
    model_limits,
    split_id,
    uint_to_float,
    uint_to_float_7fff,
)
from robocal.errors import ProtocolError, UsageError

P = 4 * math.pi


def test_type17_manual_example_request_and_reply() -> None:
    # loc_kp (0x701E) read by host 0xFD from motor 0x7F
    arb, data = encode_param_read(0xFD, 0x7F, 0x701E)
    assert arb == 0x1100FD7F
    assert data == bytes.fromhex("1E70000000000000")
    reply_id, reply = 0x11007FFD, bytes.fromhex("1E 70 00 00 00 00 F0 41")
    motor, index, ok, value = decode_param_reply(reply_id, reply)
    assert (motor, index, ok, value) == (0x7F, 0x701E, True, 30.0)
    assert encode_param_reply(0x7F, 0xFD, 0x701E, 30.0) == (reply_id, reply)


def test_param_reply_failure_status() -> None:
    arb, data = encode_param_reply(0x10, 0xFD, Param.MECH_POS, 0.0, ok=False)
    assert split_id(arb) == (17, 0x0110, 0xFD)
    assert decode_param_reply(arb, data)[2] is False


def test_position_u16_golden_vectors() -> None:
    assert float_to_uint(1.234, -P, P) == 35985 == 0x8C91
    assert uint_to_float(35985, -P, P) == pytest.approx(1.2339146, abs=1e-7)
    assert float_to_uint(0.0, -P, P) == 32767 == 0x7FFF
    assert uint_to_float(32767, -P, P) == pytest.approx(-1.9175e-4, abs=1e-8)
    assert float_to_uint(-1.0, -P, P) == 30159 == 0x75CF
    assert uint_to_float(0, -P, P) == pytest.approx(-12.566371, abs=1e-6)
    assert uint_to_float(65535, -P, P) == pytest.approx(12.566371, abs=1e-6)
    assert uint_to_float(32768, -P, P) == pytest.approx(1.9175e-4, abs=1e-8)
    # the 0x7FFF variant (Actuator-Control, robstride-dynamics)
    assert float_to_uint_7fff(1.234, P) == 35984
    assert uint_to_float_7fff(0x7FFF, P) == 0.0
    assert P_MAX_RAD == P


def test_float_to_uint_clamps() -> None:
    assert float_to_uint(100.0, -P, P) == 65535
    assert float_to_uint(-100.0, -P, P) == 0


@given(x=st.floats(-P, P))
def test_position_round_trip_within_one_lsb(x: float) -> None:
    lsb = 2 * P / 65535
    assert abs(uint_to_float(float_to_uint(x, -P, P), -P, P) - x) <= lsb
    assert abs(uint_to_float_7fff(float_to_uint_7fff(x, P), P) - x) <= 2 * lsb


def test_identifier_layout() -> None:
    assert make_id(CommType.FEEDBACK, 0x00FD, 0x01) == 0x0200FD01
    assert split_id(0x0200FD01) == (2, 0x00FD, 0x01)
    with pytest.raises(ProtocolError, match="29-bit"):
        split_id(1 << 29)
    with pytest.raises(ProtocolError, match="out of range"):
        make_id(32, 0, 0)


def test_model_table_from_the_manual() -> None:
    table = {k: (m.p_max_rad, m.v_max_rad_s, m.t_max_nm, m.kp_max, m.kd_max) for k, m in MODELS.items()}
    assert table == {
        "RS00": (P, 33.0, 14.0, 500.0, 5.0),
        "RS01": (P, 44.0, 17.0, 500.0, 5.0),
        "RS02": (P, 44.0, 17.0, 500.0, 5.0),
        "RS03": (P, 20.0, 60.0, 5000.0, 100.0),
        "RS04": (P, 15.0, 120.0, 5000.0, 100.0),
        "RS05": (P, 50.0, 5.5, 500.0, 5.0),
        "RS06": (P, 50.0, 36.0, 5000.0, 100.0),
        "EL05": (P, 50.0, 5.5, 500.0, 5.0),
    }


def test_model_table_is_not_the_sdk_table() -> None:
    # robstride-dynamics 0.0.1 / Seeed wiki: RS00 50/17, RS03 50/60, RS05 33/17, RS06 20/60 (V rad/s / T Nm)
    wrong = {"RS00": (50.0, 17.0), "RS03": (50.0, 60.0), "RS05": (33.0, 17.0), "RS06": (20.0, 60.0)}
    for name, (v, t) in wrong.items():
        m = MODELS[name]
        assert (m.v_max_rad_s, m.t_max_nm) != (v, t), name
    # MIT-chapter / LeRobot numbers are not the private-protocol ones either
    assert MODELS["RS02"].t_max_nm == 17.0 and MODELS["RS02"].v_max_rad_s == 44.0
    assert MODELS["RS04"].p_max_rad == P


def test_model_lookup_names() -> None:
    assert model_limits("rs-00") is MODELS["RS00"]
    assert model_limits("RS05") is MODELS["RS05"]
    assert model_limits("el05") is MODELS["EL05"]
    with pytest.raises(UsageError, match="unknown Robstride model 'rs-99'"):
        model_limits("rs-99")


def test_feedback_decode_rs05_scaling_and_fields() -> None:
    # mode 2 (run), fault bit 21 (uncalibrated), motor 0x0F, host 0xFD
    arb = make_id(2, (2 << 14) | (0x20 << 8) | 0x0F, 0xFD)
    data = struct.pack(">HHHH", 35985, 65535, 0, 315)
    fb = decode_feedback(arb, data, MODELS["RS05"], centred=False)  # the manual's decoder
    assert fb.motor_id == 0x0F and fb.host_id == 0xFD and fb.mode == 2 and fb.faults == 0x20
    assert fb.position_rad == pytest.approx(1.2339146, abs=1e-7)
    assert fb.velocity_rad_s == pytest.approx(50.0)
    assert fb.torque_nm == pytest.approx(-5.5)
    assert fb.temperature_c == pytest.approx(31.5)
    # the same frame read with the wrong (SDK) RS00 range would report 50 rad/s: with the manual's, 33
    assert decode_feedback(arb, data, MODELS["RS00"]).velocity_rad_s == pytest.approx(33.0)


def test_feedback_decodes_to_the_centre_of_the_truncation_cell() -> None:
    # the manual's encoder truncates: u = 35985 stands for [35985, 35986)·LSB − 4π, centre 1.2339146 + LSB/2
    arb = make_id(2, (2 << 14) | 0x0F, 0xFD)
    lsb = 2 * P / 65535
    fb = decode_feedback(arb, struct.pack(">HHHH", 35985, 65535, 0, 32767), MODELS["RS05"])
    assert fb.position_rad == pytest.approx(1.2339146 + lsb / 2, abs=1e-7)
    assert fb.velocity_rad_s == 50.0 and fb.torque_nm == pytest.approx(-5.5 + 11.0 / 65535 / 2)  # clamped top
    rest = decode_feedback(arb, struct.pack(">HHHH", 32767, 32767, 32767, 0), MODELS["RS05"])
    assert rest.position_rad == pytest.approx(0.0, abs=1e-12)  # a joint at 0 reads 0, not -1.9175e-4
    assert rest.velocity_rad_s == pytest.approx(0.0, abs=1e-12)
    assert rest.torque_nm == pytest.approx(0.0, abs=1e-12)


@given(x=st.floats(-P + 1e-3, P - 1e-3))
def test_feedback_position_error_is_centred(x: float) -> None:
    arb, data = encode_feedback(Feedback(1, 0xFD, 0, 0, x, 0.0, 0.0, 25.0), MODELS["RS00"])
    err = decode_feedback(arb, data, MODELS["RS00"]).position_rad - x
    assert abs(err) <= P / 65535 + 1e-12  # within half an LSB either side (the manual's decoder: [-1, 0] LSB)


def test_feedback_round_trip_and_malformed() -> None:
    fb = Feedback(12, 0xFD, 2, 0, 0.5, -3.0, 1.0, 28.0)
    arb, data = encode_feedback(fb, MODELS["RS00"])
    back = decode_feedback(arb, data, MODELS["RS00"])
    assert back.position_rad == pytest.approx(0.5, abs=4e-4)
    assert back.velocity_rad_s == pytest.approx(-3.0, abs=1e-3)
    assert back.torque_nm == pytest.approx(1.0, abs=1e-3)
    with pytest.raises(ProtocolError, match="payload has 7 bytes; expected 8"):
        decode_feedback(arb, data[:7], MODELS["RS00"])
    with pytest.raises(ProtocolError, match="expected feedback"):
        decode_feedback(0x1100FD7F, data, MODELS["RS00"])


def test_mit_command_torque_in_identifier() -> None:
    arb, data = encode_mit_command(14, 0.0, 0.0, 0.0, 0.0, 0.0, MODELS["RS00"])
    comm, data16, motor = split_id(arb)
    assert (comm, motor) == (1, 14)
    assert data16 == 32767  # zero torque
    assert data == struct.pack(">HHHH", 32767, 32767, 0, 0)
    m, p, v, kp, kd, t = decode_mit_command(
        *encode_mit_command(3, 1.0, 2.0, 50.0, 1.0, -2.0, MODELS["RS02"]), MODELS["RS02"]
    )
    assert m == 3
    assert (p, v, kp, kd, t) == pytest.approx((1.0, 2.0, 50.0, 1.0, -2.0), abs=1e-2)


def test_param_write_and_types() -> None:
    arb, data = encode_param_write(0xFD, 11, Param.ZERO_STA, 1)
    assert arb == make_id(18, 0xFD, 11)
    assert data == bytes([0x29, 0x70, 0, 0, 1, 0, 0, 0])
    arb, data = encode_param_write(0xFD, 11, Param.ADD_OFFSET, 1.0)
    assert data == bytes([0x2B, 0x70, 0, 0]) + struct.pack("<f", 1.0)
    with pytest.raises(UsageError, match="does not fit u8"):
        encode_param_write(0xFD, 11, Param.ZERO_STA, 300)


def test_firmware_and_fault_frames() -> None:
    arb, data = encode_firmware_reply(11, 0xFD, (0, 0, 3, 6))
    assert decode_firmware_reply(arb, data) == (11, "0.0.3.6")
    with pytest.raises(ProtocolError, match="not a firmware version reply"):
        decode_firmware_reply(arb, bytes(8))
    assert decode_fault_report(bytes([1, 0, 0, 0, 2, 0, 0, 0])) == (1, 2)
    with pytest.raises(ProtocolError, match="expected 8"):
        decode_fault_report(b"\x00")


@pytest.mark.parametrize("x", [math.nan, math.inf, -math.inf])
def test_encoders_refuse_non_finite(x: float) -> None:
    with pytest.raises(UsageError, match="expected a finite number"):
        float_to_uint(x, -1.0, 1.0)
    with pytest.raises(UsageError, match="expected a finite number"):
        float_to_uint_7fff(x, 1.0)
    with pytest.raises(UsageError, match="expected a finite number"):
        encode_mit_command(14, x, 0.0, 0.0, 0.0, 0.0, model_limits("rs-00"))
