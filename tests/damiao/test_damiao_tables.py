"""Damiao tables: model ranges, register ids and types, command bytes and state codes as the sources give them."""

from __future__ import annotations

import subprocess
import sys

import pytest

from robocal.backends.damiao.faults import FAULT_ERRORS
from robocal.backends.damiao.tables import (
    BITRATE_CODES,
    CMD_CLEAR_ERROR,
    CMD_DISABLE,
    CMD_ENABLE,
    CMD_SET_ZERO,
    MODEL_DISAGREEMENTS,
    MODELS,
    RANGE_REGISTERS,
    REGISTERS,
    STATE_NAMES,
    ControlMode,
    Register,
    State,
    model_limits,
)
from robocal.errors import UsageError


@pytest.mark.parametrize(
    ("model", "pvt"),
    [
        ("DM4310", (12.5, 30.0, 10.0)),
        ("DM4340", (12.5, 10.0, 28.0)),
        ("DM8009", (12.5, 45.0, 54.0)),
        ("DM4310_48V", (12.5, 50.0, 10.0)),
        ("DM4340_48V", (12.5, 10.0, 28.0)),
        ("DM3507", (12.5, 50.0, 5.0)),
        ("DM6006", (12.5, 45.0, 20.0)),
        ("DM8006", (12.5, 45.0, 40.0)),
        ("DM10010L", (12.5, 25.0, 200.0)),
        ("DM10010", (12.5, 20.0, 200.0)),
        ("DMH3510", (12.5, 280.0, 1.0)),
        ("DMH6215", (12.5, 45.0, 10.0)),
        ("DMG6220", (12.5, 45.0, 10.0)),
    ],
)
def test_each_model_has_the_ranges_and_a_source(model: str, pvt: tuple[float, float, float]) -> None:
    m = MODELS[model]
    assert (m.p_max_rad, m.v_max_rad_s, m.t_max_nm) == pvt
    assert m.source


def test_every_model_is_pinned_and_disagreements_are_named() -> None:
    assert len(MODELS) == 13
    assert MODEL_DISAGREEMENTS["DM4340"]["LR"][1] == 8.0 and MODELS["DM4340"].v_max_rad_s == 10.0
    assert "LR 0.6.1 says VMAX 8" in MODELS["DM4340"].source
    assert "LR says 30 / 10" in MODELS["DM3507"].source


def test_model_lookup_accepts_spellings_and_refuses_unknown_models() -> None:
    assert model_limits("dm-4310") is MODELS["DM4310"]
    with pytest.raises(UsageError, match=r"unknown Damiao model 'DM9999'.*DM4310"):
        model_limits("DM9999")


def test_register_ids_and_types_are_the_shared_numbering() -> None:
    assert RANGE_REGISTERS == (Register.PMAX, Register.VMAX, Register.TMAX) == (21, 22, 23)
    assert (Register.MST_ID, Register.ESC_ID, Register.TIMEOUT, Register.CTRL_MODE, Register.CAN_BR) == (
        7,
        8,
        9,
        10,
        35,
    )
    ints = {r for r, info in REGISTERS.items() if info.kind == "u32"}
    assert ints == {7, 8, 9, 10, 13, 14, 15, 16, 35, 36}
    assert all(REGISTERS[r].writable for r in RANGE_REGISTERS)
    assert not REGISTERS[Register.GR].writable and not REGISTERS[Register.XOUT].writable


def test_command_bytes_modes_and_bitrates() -> None:
    assert (CMD_ENABLE, CMD_DISABLE, CMD_SET_ZERO, CMD_CLEAR_ERROR) == (0xFC, 0xFD, 0xFE, 0xFB)
    assert [int(m) for m in ControlMode] == [1, 2, 3, 4]
    assert BITRATE_CODES[4] == 1_000_000 and BITRATE_CODES[9] == 5_000_000


def test_every_state_code_is_named_and_every_error_state_has_an_error() -> None:
    assert {int(s) for s in State} == {0x0, 0x1, 0x8, 0x9, 0xA, 0xB, 0xC, 0xD, 0xE}
    assert set(STATE_NAMES) == set(State)
    assert set(FAULT_ERRORS) == set(State) - {State.DISABLED, State.ENABLED}
    assert len({cls.__name__ for cls in FAULT_ERRORS.values()}) == 7


def test_the_protocol_layer_imports_without_python_can() -> None:
    """tables, protocol, modes and faults are pure: importing them loads neither python-can nor numpy."""
    code = (
        "import sys; import robocal.backends.damiao.modes, robocal.backends.damiao.faults; "
        "print(sorted(m for m in ('can', 'numpy') if m in sys.modules))"
    )
    out = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, timeout=120, check=True
    )
    assert out.stdout.strip() == "[]"
