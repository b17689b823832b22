"""Damiao non-MIT command frames (POS_VEL, VEL, POS_FORCE) and the 0x7FF requests as a motor reads them."""

from __future__ import annotations

import math

import pytest
from hypothesis import given
from hypothesis import strategies as st

from robocal.backends.damiao.modes import (
    PosForceCommand,
    decode_pos_force,
    decode_pos_vel,
    decode_vel,
    encode_pos_force,
    encode_pos_vel,
    encode_vel,
)
from robocal.backends.damiao.protocol import (
    ConfigRequest,
    decode_config_request,
    refresh_frame,
    register_read_frame,
    register_write_frame,
    save_frame,
    unpack_register_value,
)
from robocal.backends.damiao.tables import OP_READ, OP_REFRESH, OP_SAVE, OP_WRITE, Register
from robocal.errors import ProtocolError, UsageError


def test_mode_frames_are_the_reference_bytes() -> None:
    assert encode_pos_vel(0x01, 1.0, 2.0) == (0x101, bytes.fromhex("0000803F00000040"))
    assert encode_vel(0x01, 3.0) == (0x201, bytes.fromhex("00004040"))
    assert encode_pos_force(0x01, PosForceCommand(0.5, 2.0, 0.3)) == (
        0x301,
        bytes.fromhex("0000003FC800B80B"),
    )


def test_mode_frames_decode_back() -> None:
    assert decode_pos_vel(bytes.fromhex("0000803F00000040")) == (1.0, 2.0)
    assert decode_vel(bytes.fromhex("00004040")) == 3.0
    assert decode_pos_force(bytes.fromhex("0000003FC800B80B")) == PosForceCommand(0.5, 2.0, 0.3)


def test_pos_force_limits_clamp_and_bad_input_is_refused() -> None:
    _, data = encode_pos_force(2, PosForceCommand(0.0, 500.0, -1.0))
    assert decode_pos_force(data) == PosForceCommand(0.0, 100.0, 0.0)
    with pytest.raises(UsageError, match="velocity: cannot encode nan"):
        encode_vel(1, math.nan)
    with pytest.raises(UsageError, match="VEL command id"):
        encode_vel(0x600, 1.0)
    with pytest.raises(ProtocolError, match="8 bytes; expected 4"):
        decode_vel(bytes(8))


@given(
    q=st.floats(-100.0, 100.0),
    v=st.floats(0.0, 100.0),
    i=st.floats(0.0, 1.0),
)
def test_pos_force_round_trip_is_within_one_step(q: float, v: float, i: float) -> None:
    back = decode_pos_force(encode_pos_force(3, PosForceCommand(q, v, i))[1])
    assert back.position_rad == pytest.approx(q, rel=1e-6, abs=1e-30)
    # float32 arithmetic as openarm_can does it: truncated to the step, give or take float32's rounding
    assert v - 0.01 - 1e-5 <= back.velocity_rad_s <= v + 1e-5
    assert i - 1e-4 - 1e-7 <= back.current_limit_pu <= i + 1e-7


def test_config_requests_read_back_as_sent() -> None:
    assert decode_config_request(refresh_frame(8)[1]) == ConfigRequest(8, OP_REFRESH, 0, bytes(4))
    assert decode_config_request(register_read_frame(5, Register.PMAX)[1]) == ConfigRequest(
        5, OP_READ, 21, bytes(4)
    )
    write = decode_config_request(register_write_frame(0x7FF, Register.VMAX, 10.0)[1])
    assert (write.can_id, write.op, write.register) == (0x7FF, OP_WRITE, 22)
    assert unpack_register_value(write.register, write.value) == 10.0
    assert decode_config_request(save_frame(5)[1]).op == OP_SAVE
    with pytest.raises(ProtocolError, match="op byte 0x44"):
        decode_config_request(bytes.fromhex("0500441500000000"))
