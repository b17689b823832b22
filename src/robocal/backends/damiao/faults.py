"""Damiao state codes as named errors: one :class:`DamiaoFaultError` subclass per error code of a state frame.

The code is the high nibble of byte 0 of every state frame (DMP ``motor.py`` constants; OAC-PyPI ``MotorError``
names). Faults are device failures (exit 3); a code no source names is a :class:`~robocal.errors.ProtocolError`.
"""

from __future__ import annotations

from typing import ClassVar

from ...errors import DeviceError, ProtocolError
from .tables import STATE_NAMES, State

__all__ = [
    "FAULT_ERRORS",
    "DamiaoFaultError",
    "DamiaoLostCommError",
    "DamiaoMosOverTempError",
    "DamiaoOverCurrentError",
    "DamiaoOverVoltageError",
    "DamiaoOverloadError",
    "DamiaoRotorOverTempError",
    "DamiaoUnderVoltageError",
    "DamiaoUnknownStateError",
    "fault_error",
]


class DamiaoFaultError(DeviceError):
    """A Damiao motor reported an error state in its state frame (exit 3).

    Attributes:
        state: The :class:`~robocal.backends.damiao.tables.State` code.
        motor: The motor's name or id as the message gives it.
    """

    state: ClassVar[State]

    def __init__(self, motor: str) -> None:
        self.motor = motor
        super().__init__(
            f"Damiao motor {motor} reports {STATE_NAMES[self.state]} (state {int(self.state):#x}); "
            "clear it with the clear-error command (0xFB) once the cause is gone"
        )


class DamiaoOverVoltageError(DamiaoFaultError):
    """State 0x8: supply above the OV_Value threshold."""

    state = State.OVER_VOLTAGE


class DamiaoUnderVoltageError(DamiaoFaultError):
    """State 0x9: supply below the UV_Value threshold."""

    state = State.UNDER_VOLTAGE


class DamiaoOverCurrentError(DamiaoFaultError):
    """State 0xA: current above the OC_Value threshold."""

    state = State.OVER_CURRENT


class DamiaoMosOverTempError(DamiaoFaultError):
    """State 0xB: MOSFET over-temperature."""

    state = State.MOS_OVER_TEMP


class DamiaoRotorOverTempError(DamiaoFaultError):
    """State 0xC: rotor (coil) over-temperature (reported latching after a joint was driven into a stop)."""

    state = State.ROTOR_OVER_TEMP


class DamiaoLostCommError(DamiaoFaultError):
    """State 0xD: no command within the TIMEOUT register's time."""

    state = State.LOST_COMM


class DamiaoOverloadError(DamiaoFaultError):
    """State 0xE: overload."""

    state = State.OVERLOAD


class DamiaoUnknownStateError(ProtocolError):
    """A state nibble no source names (0x2-0x7, 0xF): a garbled frame or firmware robocal does not know."""


FAULT_ERRORS: dict[State, type[DamiaoFaultError]] = {
    cls.state: cls
    for cls in (
        DamiaoOverVoltageError,
        DamiaoUnderVoltageError,
        DamiaoOverCurrentError,
        DamiaoMosOverTempError,
        DamiaoRotorOverTempError,
        DamiaoLostCommError,
        DamiaoOverloadError,
    )
}
"""Error state → its error class."""


def fault_error(code: int, motor: str) -> DeviceError | None:
    """The error a state code stands for, None for DISABLED / ENABLED.

    Returns:
        A :class:`DamiaoFaultError` subclass instance for 0x8-0xE, a :class:`DamiaoUnknownStateError` for a
        code no source names, None for 0x0 and 0x1.
    """
    if code in (State.DISABLED, State.ENABLED):
        return None
    if code in State._value2member_map_:
        return FAULT_ERRORS[State(code)](motor)
    return DamiaoUnknownStateError(
        f"Damiao motor {motor} sent unknown state {code:#x} in byte 0 of its state frame"
    )
