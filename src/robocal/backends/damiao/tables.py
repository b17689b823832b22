"""Damiao CAN motors as data: model ranges, register ids, command bytes, control modes and state codes.

No code beyond lookups. Every value names where it was read (docs/damiao.md lists the sources in full):

* ``LR``  LeRobot 0.6.1, ``lerobot/motors/damiao/tables.py`` and ``damiao.py``;
* ``OAC`` enactic/openarm_can (commit 98666042, 2026-08-01), ``dm_motor_constants.hpp``, ``dm_motor_control.cpp``
  and its CLI;
* ``DMP`` PyPI ``damiao-motor`` 1.0.6, ``core/motor.py``.

The three agree on everything here except the two model rows :data:`MODEL_DISAGREEMENTS` lists. The ranges a
motor actually encodes with are its own registers PMAX / VMAX / TMAX (:data:`RANGE_REGISTERS`); the table is
only what a backend assumes before it has read them.
"""

from __future__ import annotations

from dataclasses import dataclass
from enum import IntEnum

from ...errors import UsageError

__all__ = [
    "BITRATE_CODES",
    "CMD_CLEAR_ERROR",
    "CMD_DISABLE",
    "CMD_ENABLE",
    "CMD_SET_ZERO",
    "CONFIG_ID",
    "ID_MAX",
    "KD_MAX",
    "KP_MAX",
    "MODELS",
    "MODEL_DISAGREEMENTS",
    "MODE_ID_OFFSETS",
    "OP_READ",
    "OP_REFRESH",
    "OP_SAVE",
    "OP_SAVE_ALT",
    "OP_WRITE",
    "RANGE_REGISTERS",
    "REGISTERS",
    "STATE_NAMES",
    "ControlMode",
    "MotorLimits",
    "Register",
    "RegisterInfo",
    "State",
    "model_limits",
]

ID_MAX = 0x7FF
"""Largest 11-bit standard CAN id: every Damiao frame uses standard ids (LR ``is_extended_id=False``)."""
CONFIG_ID = 0x7FF
"""Arbitration id of the refresh and register frames, whichever motor they address (LR, OAC)."""

CMD_ENABLE = 0xFC
"""Last byte of the special frame that switches the motor on (``FF×7 FC``; LR, OAC)."""
CMD_DISABLE = 0xFD
"""Last byte of the special frame that switches the motor off (LR, OAC)."""
CMD_SET_ZERO = 0xFE
"""Last byte of the special frame that makes the current output position zero (LR, OAC, DMP)."""
CMD_CLEAR_ERROR = 0xFB
"""Last byte of the special frame that clears a latched error (OAC CLI, DMP; LeRobot has none)."""

OP_REFRESH = 0xCC
"""Byte 2 of the frame to 0x7FF that asks a motor for a state frame (LR ``_refresh_motor``, OAC)."""
OP_READ = 0x33
"""Byte 2 of a register read (and of its reply) (OAC ``pack_query_param_data``)."""
OP_WRITE = 0x55
"""Byte 2 of a register write to RAM (and of the motor's echo) (OAC ``pack_write_param_data``)."""
OP_SAVE = 0xAA
"""Byte 2 of the frame that saves the registers to flash (~10 000 write cycles; OAC CLI, OA docs)."""
OP_SAVE_ALT = (0x00, 0x01)
"""Byte 3 of a save frame: OAC sends 0x00, DMP 0x01; robocal sends 0x00 and reads either."""

KP_MAX = 500.0
"""MIT stiffness range 0..500 N·m/rad (LR ``MIT_KP_RANGE``, OAC, DMP ``KP_MAX``)."""
KD_MAX = 5.0
"""MIT damping range 0..5 N·m·s/rad (LR ``MIT_KD_RANGE``, OAC, DMP ``KD_MAX``)."""


@dataclass(frozen=True)
class MotorLimits:
    """The ranges one Damiao model maps its MIT command and state fields onto.

    Attributes:
        model: Model name as the host stacks spell it (``"DM4310"``).
        p_max_rad: Position range ±PMAX, rad (register 21).
        v_max_rad_s: Velocity range ±VMAX, rad/s (register 22).
        t_max_nm: Torque range ±TMAX, N·m (register 23).
        source: Where the three numbers were read.
    """

    model: str
    p_max_rad: float
    v_max_rad_s: float
    t_max_nm: float
    source: str


_AGREED = "LR tables.py, OAC dm_motor_constants.hpp and DMP _MOTOR_LIMIT_PARAM agree"

MODELS: dict[str, MotorLimits] = {
    m.model: m
    for m in (
        MotorLimits(
            "DM3507", 12.5, 50.0, 5.0, "OAC and DMP (VMAX 50, TMAX 5); LR says 30 / 10; DMP PMAX 12.566"
        ),
        MotorLimits("DM4310", 12.5, 30.0, 10.0, _AGREED),
        MotorLimits("DM4310_48V", 12.5, 50.0, 10.0, _AGREED + " (DMP: 4310P)"),
        MotorLimits(
            "DM4340", 12.5, 10.0, 28.0, "OAC since 25f8f44 (2026-07-17) and DMP; LR 0.6.1 says VMAX 8"
        ),
        MotorLimits("DM4340_48V", 12.5, 10.0, 28.0, _AGREED + " (DMP: 4340P)"),
        MotorLimits("DM6006", 12.5, 45.0, 20.0, _AGREED),
        MotorLimits("DM8006", 12.5, 45.0, 40.0, _AGREED),
        MotorLimits("DM8009", 12.5, 45.0, 54.0, _AGREED),
        MotorLimits("DM10010L", 12.5, 25.0, 200.0, _AGREED),
        MotorLimits("DM10010", 12.5, 20.0, 200.0, _AGREED),
        MotorLimits("DMH3510", 12.5, 280.0, 1.0, _AGREED),
        MotorLimits("DMH6215", 12.5, 45.0, 10.0, _AGREED + " (DMP: G6215)"),
        MotorLimits("DMG6220", 12.5, 45.0, 10.0, _AGREED + " (DMP: H6220)"),
    )
}
"""Model → the ranges assumed until the motor's own PMAX / VMAX / TMAX registers are read (same order as LR
``MOTOR_LIMIT_PARAMS`` and OAC ``MotorType``)."""

MODEL_DISAGREEMENTS: dict[str, dict[str, tuple[float, float, float]]] = {
    "DM3507": {"LR": (12.5, 30.0, 10.0), "OAC": (12.5, 50.0, 5.0), "DMP": (12.566, 50.0, 5.0)},
    "DM4340": {"LR": (12.5, 8.0, 28.0), "OAC": (12.5, 10.0, 28.0), "DMP": (12.5, 10.0, 28.0)},
}
"""Where the host stacks' tables differ: model → stack → (PMAX, VMAX, TMAX). LeRobot 0.6.1 scales every DM4340
velocity (OpenArm J3, J4) by VMAX 8 against a motor set to 10."""


def model_limits(model: str) -> MotorLimits:
    """The table row of ``model``, accepting ``"dm4310"``, ``"DM-4310"``, ``"DM4310"``.

    Raises:
        UsageError: Unknown model (the message lists the known ones).
    """
    key = model.strip().upper().replace("-", "")
    if key not in MODELS:
        raise UsageError(f"unknown Damiao model {model!r}; expected one of {', '.join(MODELS)}")
    return MODELS[key]


class Register(IntEnum):
    """Register ids (RID): the same numbers in LR ``MotorVariable``, OAC ``RID`` and DMP ``REGISTER_TABLE``."""

    UV_VALUE = 0
    KT_VALUE = 1
    OT_VALUE = 2
    OC_VALUE = 3
    ACC = 4
    DEC = 5
    MAX_SPD = 6
    MST_ID = 7
    ESC_ID = 8
    TIMEOUT = 9
    CTRL_MODE = 10
    DAMP = 11
    INERTIA = 12
    HW_VER = 13
    SW_VER = 14
    SN = 15
    NPP = 16
    RS = 17
    LS = 18
    FLUX = 19
    GR = 20
    PMAX = 21
    VMAX = 22
    TMAX = 23
    I_BW = 24
    KP_ASR = 25
    KI_ASR = 26
    KP_APR = 27
    KI_APR = 28
    OV_VALUE = 29
    GREF = 30
    DETA = 31
    V_BW = 32
    IQ_C1 = 33
    VL_C1 = 34
    CAN_BR = 35
    SUB_VER = 36
    U_OFF = 50
    V_OFF = 51
    K1 = 52
    K2 = 53
    M_OFF = 54
    DIR = 55
    P_M = 80
    XOUT = 81


@dataclass(frozen=True)
class RegisterInfo:
    """How one register is typed and whether it may be written.

    Attributes:
        kind: ``"u32"`` or ``"f32"``: the 4 value bytes, little-endian.
        writable: RW (True) or read-only (False).
        meaning: One line on what it holds.
    """

    kind: str
    writable: bool
    meaning: str


_U32 = {
    Register.MST_ID,
    Register.ESC_ID,
    Register.TIMEOUT,
    Register.CTRL_MODE,
    Register.HW_VER,
    Register.SW_VER,
    Register.SN,
    Register.NPP,
    Register.CAN_BR,
    Register.SUB_VER,
}
"""Integer registers: RID 7-10, 13-16, 35-36 (OAC ``is_in_ranges``); every other one is a float32."""
_READ_ONLY = {
    Register.DAMP,
    Register.INERTIA,
    Register.HW_VER,
    Register.SW_VER,
    Register.SN,
    Register.NPP,
    Register.RS,
    Register.LS,
    Register.FLUX,
    Register.GR,
    Register.SUB_VER,
    Register.U_OFF,
    Register.V_OFF,
    Register.K1,
    Register.K2,
    Register.M_OFF,
    Register.DIR,
    Register.P_M,
    Register.XOUT,
}
_MEANING = {
    Register.UV_VALUE: "under-voltage threshold, V",
    Register.KT_VALUE: "torque constant",
    Register.OT_VALUE: "over-temperature threshold, °C",
    Register.OC_VALUE: "over-current threshold, per unit",
    Register.MST_ID: "feedback id: the arbitration id of the motor's replies",
    Register.ESC_ID: "receive id: the id the motor listens on (MIT commands, special frames)",
    Register.TIMEOUT: "communication-loss alarm time, 1 unit = 50 µs (DMP: ms × 20); 0 assumed to disable it",
    Register.CTRL_MODE: "control mode (ControlMode: 1 MIT, 2 POS_VEL, 3 VEL, 4 POS_FORCE)",
    Register.NPP: "pole pairs",
    Register.GR: "gear ratio",
    Register.PMAX: "position mapping range ±PMAX of the MIT and state frames, rad",
    Register.VMAX: "velocity mapping range ±VMAX of the MIT and state frames, rad/s",
    Register.TMAX: "torque mapping range ±TMAX of the MIT and state frames, N·m",
    Register.CAN_BR: "CAN bit-rate code (BITRATE_CODES)",
    Register.M_OFF: "mechanical (angle) offset",
    Register.DIR: "direction (typed float and read-only by OAC's read table, integer by its writer)",
    Register.P_M: "motor-side position, rad",
    Register.XOUT: "output-shaft position, rad",
}

REGISTERS: dict[Register, RegisterInfo] = {
    r: RegisterInfo("u32" if r in _U32 else "f32", r not in _READ_ONLY, _MEANING.get(r, r.name))
    for r in Register
}
"""Register → its type, access and meaning (OAC ``motor_read_param_commands.cpp``, DMP)."""

RANGE_REGISTERS: tuple[Register, Register, Register] = (Register.PMAX, Register.VMAX, Register.TMAX)
"""The registers a backend reads at connect time for the MIT / state scaling, in (P, V, T) order."""


class ControlMode(IntEnum):
    """Values of register CTRL_MODE (10) (OAC ``ControlMode``, LR ``ControlMode``)."""

    MIT = 1
    POS_VEL = 2
    VEL = 3
    POS_FORCE = 4


MODE_ID_OFFSETS: dict[ControlMode, int] = {
    ControlMode.MIT: 0x000,
    ControlMode.POS_VEL: 0x100,
    ControlMode.VEL: 0x200,
    ControlMode.POS_FORCE: 0x300,
}
"""Control mode → offset added to ESC_ID for its command frames (OAC ``dm_motor_control.cpp``)."""

BITRATE_CODES: dict[int, int] = {
    0: 125_000,
    1: 200_000,
    2: 250_000,
    3: 500_000,
    4: 1_000_000,
    5: 2_000_000,
    6: 2_500_000,
    7: 3_200_000,
    8: 4_000_000,
    9: 5_000_000,
    10: 8_000_000,
    11: 10_000_000,
}
"""Register CAN_BR (35) code → bit/s (LR ``AVAILABLE_BAUDRATES`` 0-9; codes 10 and 11 only in OAC's CLI)."""


class State(IntEnum):
    """State / error code: the high nibble of byte 0 of a state frame (DMP constants, OAC-PyPI ``MotorError``)."""

    DISABLED = 0x0
    ENABLED = 0x1
    OVER_VOLTAGE = 0x8
    UNDER_VOLTAGE = 0x9
    OVER_CURRENT = 0xA
    MOS_OVER_TEMP = 0xB
    ROTOR_OVER_TEMP = 0xC
    LOST_COMM = 0xD
    OVERLOAD = 0xE


STATE_NAMES: dict[State, str] = {
    State.DISABLED: "disabled",
    State.ENABLED: "enabled",
    State.OVER_VOLTAGE: "over-voltage",
    State.UNDER_VOLTAGE: "under-voltage",
    State.OVER_CURRENT: "over-current",
    State.MOS_OVER_TEMP: "MOSFET over-temperature",
    State.ROTOR_OVER_TEMP: "rotor (coil) over-temperature",
    State.LOST_COMM: "communication lost (TIMEOUT expired)",
    State.OVERLOAD: "overload",
}
"""State → the words robocal's messages use. OAC-PyPI's names (OVERVOLTAGE, COIL_OVERHEAT, ...) are assumed to
carry DMP's numbers: its bindings do not show them."""
