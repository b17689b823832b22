"""The host-loss watchdog of a simulated Dynamixel X servo: ``Bus_Watchdog`` (98), as the e-Manual describes it.

``Bus_Watchdog`` 1..127 arms it (unit 20 ms), 0 disarms it and clears its error, −1 is the error. While
``Torque_Enable`` is 1, a servo that hears no instruction packet for longer than the set time **stops**:
``Bus_Watchdog`` becomes −1 and the goal registers (``Goal_PWM``, ``Goal_Current``, ``Goal_Velocity``,
``Goal_Position``) turn read-only, a write to them answered with a Data Range error (4), until ``Bus_Watchdog`` is
written 0. The e-Manual says only that the servo "will stop" (its profile applied as 0); modelled here: a position
mode (3, 4, 5) holds where the joint is (goal = present position), velocity mode gets ``Goal_Velocity`` 0,
current mode ``Goal_Current`` 0, PWM mode ``Goal_PWM`` 0; the torque stays on. The e-Manual counts "all the
Instruction Packet": every packet a servo hears resets its timer (also packets for other ids, an assumption).

Time is the bus's simulated clock when it has one (the trip lands at exactly the last packet + the set time: the
firmware is integrated up to it under the old goal first), else the monotonic clock (checked by the bus thread).
Feetech STS/SCS servos have no such register (their memory table has none): nothing here applies to them.
"""

from __future__ import annotations

from collections.abc import Iterable
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from .servo_model import SimServo

__all__ = ["UNIT_S", "due_s", "heard", "trip", "trip_if_due", "write_error"]

UNIT_S = 0.02
"""One ``Bus_Watchdog`` unit (s)."""
_GOALS = ("Goal_PWM", "Goal_Current", "Goal_Velocity", "Goal_Position")


def _watchdog(servo: SimServo) -> int:
    if "Bus_Watchdog" not in servo.table:  # only the Dynamixel X table has it
        return 0
    return servo.get_reg("Bus_Watchdog")


def due_s(servo: SimServo) -> float | None:
    """When the armed watchdog of a servo with torque on trips if nothing is heard (None: it cannot trip)."""
    units = _watchdog(servo)
    if units <= 0 or servo.watchdog_rx_s is None or not servo.get_reg("Torque_Enable"):
        return None
    return servo.watchdog_rx_s + units * UNIT_S


def trip(servo: SimServo, at_s: float) -> None:
    """The watchdog fires at ``at_s``: ``Bus_Watchdog`` −1, the servo stops (see the module docstring)."""
    mode = servo.get_reg("Operating_Mode")
    if mode in (3, 4, 5):
        if servo.firmware is not None:
            servo.firmware.setpoint_ticks = servo.actual_ticks
        servo.set_reg("Goal_Position", servo.present_ticks())
    elif mode == 1:
        servo.set_reg("Goal_Velocity", 0)
    elif mode == 0:
        servo.set_reg("Goal_Current", 0)
    elif mode == 16:
        servo.set_reg("Goal_PWM", 0)
    servo.set_reg("Bus_Watchdog", -1)
    servo.watchdog_trips.append((servo.watchdog_rx_s or 0.0, at_s))


def trip_if_due(servo: SimServo, now_s: float) -> bool:
    """Fire the watchdog if it is due by ``now_s``; with physics, the joint is first integrated up to the trip."""
    due = due_s(servo)
    if due is None or now_s < due:
        return False
    if servo.firmware is not None:
        servo.firmware.sync(until_s=due)
    trip(servo, due)
    return True


def heard(servos: Iterable[SimServo], now_s: float) -> None:
    """An instruction packet reached these servos at ``now_s`` (their watchdogs restart)."""
    for servo in servos:
        servo.watchdog_rx_s = now_s


def write_error(servo: SimServo, addr: int, data: bytes) -> int:
    """4 (Data Range error) for a goal write while the watchdog's error stands, else 0."""
    if _watchdog(servo) != -1:
        return 0
    for name in _GOALS:
        if name in servo.table:
            start, size = servo.table[name]
            if addr < start + size and start < addr + len(data):
                return 4
    return 0
