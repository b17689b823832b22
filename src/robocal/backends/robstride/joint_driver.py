"""A Robstride motor as a joint driver of the automatic hard-stop calibration (MIT frames over python-can).

The stop search's commands, gains, keep-alive and limp bookkeeping are the shared
:class:`~robocal.backends.mit_joint_driver.MitJointDriver`'s; this adapter holds what is Robstride's: the type-1
MIT frame and its feedback (fault bits, run mode), the ``limit_torque`` parameter set on enable, ``canTimeout`` as
the host-loss watchdog, type 4 stop for limp and fault clear.
"""

from __future__ import annotations

import math
from contextlib import suppress
from typing import Any, ClassVar

from ...core.stop_search import StopSample
from ...errors import CalibTimeoutError, DeviceError
from ..mit_joint_driver import MitJointDriver, MitTarget
from ..mit_keepalive import KEEPALIVE_S
from .bus import CAN_TIMEOUT_UNITS_PER_S
from .protocol import P_MAX_RAD, Param

LIMIT_TORQUE = 0x700B
"""Robstride ``limit_torque`` parameter (f32, N·m; RAM until a type-22 save, which robocal never sends)."""
WATCHDOG_S = 0.5
"""The host-loss watchdog armed on every motor that moves: ``canTimeout`` so that a motor that hears no frame for
this long (a killed process, a pulled cable, a host held up) enters reset mode on its own."""

__all__ = [
    "KEEPALIVE_S",
    "MAX_LAG_RAD",
    "ROBSTRIDE_FATAL_BITS",
    "ROBSTRIDE_OVERCURRENT_BIT",
    "WATCHDOG_S",
    "RobstrideJointDriver",
    "RobstrideWatchdogError",
]


class RobstrideWatchdogError(DeviceError):
    """A motor left run mode on its own while robocal drove it: its CAN timeout tripped (the host was silent)."""


MAX_LAG_RAD = math.radians(3.0)
"""The position target leads a Robstride joint by at most this: ``kp = cap / 3°`` (``sweep --auto``, its sim)."""


# ------------------------------------------------------------------------------------------------ Robstride
ROBSTRIDE_OVERCURRENT_BIT = (1 << 4) | (1 << 1)
"""Type-2 fault bits 20 (stall/overload) and 17 (over-current): suspect evidence only (re-read to confirm)."""
ROBSTRIDE_FATAL_BITS = (1 << 0) | (1 << 2) | (1 << 3) | (1 << 5)
"""Bits 16 under-voltage, 18 over-temperature, 19 magnetic encoder, 21 uncalibrated end the run."""


class RobstrideJointDriver(MitJointDriver):
    """A Robstride motor driven with MIT frames (type 1) through :class:`~robocal.backends.robstride.RobstrideBus`.

    The search's commands as :class:`~robocal.backends.mit_joint_driver.MitJointDriver` maps them; ``limp``: MIT
    ``(0, 0, 0, 0, 0)`` then type 4 (stop), both also sent first without awaiting a reply (``torque_off_nowait``,
    the first frames of every ``limp_all``: a motor that stopped answering no longer holds another's stop back by
    its reply waits); ``reread``: the last command again (a motor found out of run mode is a tripped watchdog,
    raised), type 4 stop with fault clear, type 3 enable, the last command again. The firmware's ``limit_torque`` (0x700B, a RAM parameter: type 18, never saved to flash) is set
    to ``1.05·cap`` when the motor is first enabled, so a rebound or a control-period delay can never push harder
    than the cap + 5 %; :meth:`limp` writes the value read before back (a power cycle restores it too). The cap,
    ``limit_torque`` and every feed-forward torque stay within the hard ceiling of the motor model's rating
    (:attr:`ceiling_nm`, from the bus's model name and :mod:`robocal.core.motor_models`).

    Args: as :class:`~robocal.backends.mit_joint_driver.MitJointDriver`.
    """

    MAX_LAG_RAD: ClassVar[float] = MAX_LAG_RAD
    WATCHDOG_S: ClassVar[float] = WATCHDOG_S

    def __init__(self, bus: Any, name: str, direction: int, cap_nm: float, max_lag_rad: float, clock: Any,
                 **kwargs: Any) -> None:  # fmt: skip
        super().__init__(bus, name, direction, cap_nm, max_lag_rad, clock, **kwargs)
        self._saved_limit: float | None = None

    def position_range_rad(self) -> float:
        """±4π rad on every Robstride model (the type-2 feedback's position field)."""
        return P_MAX_RAD

    def _sample(self, fb: Any) -> StopSample:
        d = self.direction
        if fb.faults & ROBSTRIDE_FATAL_BITS:
            raise DeviceError(f"joint {self.name}: motor fault bits {fb.faults:#04x}")
        if self.enabled and getattr(fb, "mode", 2) != 2:
            self.enabled = False
            raise RobstrideWatchdogError(
                f"joint {self.name}: the motor left run mode on its own (mode {fb.mode}): its CAN timeout "
                f"({self.watchdog_s:g} s) stopped it because no frame reached it in time (robocal was held up or "
                "the bus dropped frames)"
            )
        s = StopSample(
            self.clock.now(),
            d * fb.position_rad,
            d * fb.velocity_rad_s,
            d * fb.torque_nm,
            True,
            bool(fb.faults & ROBSTRIDE_OVERCURRENT_BIT),
        )
        self._q = s.q_rad
        return s

    def _exchange(self, target: MitTarget) -> StopSample:
        d = self.direction
        p, v, kp, kd, t = target
        return self._sample(self.bus.mit_command(self.name, d * p, d * v, kp, kd, d * t))

    def _switch_on(self) -> StopSample:
        try:
            if self._saved_limit is None:
                self._saved_limit = float(self.bus.read_param(self.name, LIMIT_TORQUE))
                self.bus.write_param(self.name, LIMIT_TORQUE, min(1.05 * self.cap_nm, self.ceiling_nm))
            self.arm_watchdog()
            fb = self.bus.enable(self.name)
        except CalibTimeoutError:
            return StopSample(self.clock.now(), math.nan, ok=False)
        self.enabled = True
        s = self._sample(fb)
        self._last = MitTarget(0.0, 0.0, 0.0, self.kd, 0.0)  # damping only until the first command: enabling never moves
        return s

    def _clear_fault(self) -> bool:
        """Clear an overload latch (type 4 with fault clear); a motor that left run mode meanwhile ends the run.

        The motor is asked first, with its last command again (what it is under anyway): a re-read follows a lost
        reply as well as an overload, and a motor whose ``canTimeout`` tripped meanwhile (robocal held up past it:
        reset mode, limp, perhaps dropped) answers in reset mode, which :meth:`_sample` raises as the fault it is
        (:class:`RobstrideWatchdogError`) instead of it being cleared, enabled and driven on.
        """
        try:
            self._exchange(self._clamped(self._last))
        except CalibTimeoutError:
            return True
        with suppress(CalibTimeoutError):
            self.bus.stop(self.name, clear_faults=True)
        return False

    def _read_watchdog(self) -> float | None:
        if getattr(self.bus, "arm_watchdog", None) is None:
            return None  # a bus without canTimeout
        return float(self.bus.read_param(self.name, Param.CAN_TIMEOUT)) / CAN_TIMEOUT_UNITS_PER_S

    def _write_watchdog(self, timeout_s: float) -> None:
        self.bus.disarm_watchdog(self.name, timeout_s)  # writes canTimeout (the bus's arm_watchdog reads it first)

    def _torque_off_nowait(self) -> None:
        self.bus.torque_off_nowait([self.name])

    def _torque_off(self) -> None:
        with suppress(Exception):
            self.bus.mit_command(self.name, 0.0, 0.0, 0.0, 0.0, 0.0)
        with suppress(Exception):
            self.bus.stop(self.name)
        if self._saved_limit is not None:
            with suppress(Exception):
                self.bus.write_param(self.name, LIMIT_TORQUE, self._saved_limit)
                self._saved_limit = None
