"""A Damiao motor as a joint driver of the automatic hard-stop calibration (MIT frames through ``DamiaoBus``).

The stop search's commands, gains, keep-alive and limp bookkeeping are the shared
:class:`~robocal.backends.mit_joint_driver.MitJointDriver`'s; this adapter holds what is Damiao's. The bus must be
opened with ``allow_motion=True`` (the guarded path: ``robocal sweep --auto`` enters the motion guard first).
Nothing is written to a motor's flash: the host-loss watchdog (TIMEOUT, register 9) is a RAM write put back by
:meth:`DamiaoJointDriver.limp`, and the motor must already be in MIT mode (CTRL_MODE 1, which LeRobot and
openarm_can also assume; robocal reads it and refuses otherwise, it never changes it).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from contextlib import suppress
from typing import ClassVar

from ...core.stop_search import StopSample
from ...errors import CalibTimeoutError, DeviceError
from ..mit_joint_driver import MitJointDriver, MitTarget
from ..mit_keepalive import KEEPALIVE_S, WATCHDOG_MIN_S
from .faults import DamiaoLostCommError, DamiaoOverloadError, fault_error
from .protocol import MitCommand, MotorState
from .tables import ControlMode, Register, State

__all__ = ["KEEPALIVE_S", "MAX_LAG_RAD", "WATCHDOG_S", "DamiaoJointDriver", "DamiaoWatchdogError"]

MAX_LAG_RAD = math.radians(3.0)
"""The position target leads the joint by at most this: ``kp = cap / 3°``."""
TIMEOUT_UNIT_S = 50e-6
"""One unit of TIMEOUT (register 9): 50 µs."""
WATCHDOG_S = WATCHDOG_MIN_S
"""TIMEOUT armed on every motor that moves when replies are quick (0.5 s): a motor that hears no frame for this
long goes to state 0xD and limp. A longer reply wait arms ``watchdog_for(reply wait)`` (over twice the wait; a
wait needing more than 2 s is refused: :func:`robocal.backends.mit_keepalive.watchdog_for`)."""


class DamiaoWatchdogError(DeviceError):
    """A motor reported communication lost (0xD) while robocal drove it: its TIMEOUT tripped (the host was silent)."""


class DamiaoJointDriver(MitJointDriver):
    """A Damiao motor driven with MIT frames through :class:`~robocal.backends.damiao.bus.DamiaoBus`.

    The search's commands as :class:`~robocal.backends.mit_joint_driver.MitJointDriver` maps them (a push asks at
    most the cap); ``limp``: the zero-torque MIT frame, then disable (0xFD), TIMEOUT put back; ``reread``: clear
    error (0xFB), enable (0xFC), the last command again. Angles are in the joint's frame ``s =
    direction·reading`` (the reading is relative to the motor's stored zero). ``torque_off_nowait``: the
    no-torque MIT frame and disable, sent without awaiting a reply (the first frames of every ``limp_all``). An overload state (0xE) is suspect
    evidence (the search re-reads); every other error state ends the run. TIMEOUT is armed over twice the reply
    wait (:func:`~robocal.backends.mit_keepalive.watchdog_for`), and on a live bus the run's idle motors are kept
    alive from a thread of their own.

    Args: as :class:`~robocal.backends.mit_joint_driver.MitJointDriver`.

    Raises:
        UsageError: The reply wait needs a watchdog longer than robocal arms (before anything is sent).
    """

    MAX_LAG_RAD: ClassVar[float] = MAX_LAG_RAD
    WATCHDOG_S: ClassVar[float] = WATCHDOG_S
    WATCHDOG_FOLLOWS_REPLY_WAIT: ClassVar[bool] = True
    KEEPALIVE_THREAD: ClassVar[bool] = True
    KEEPALIVE_IGNORES: ClassVar[tuple[type[BaseException], ...]] = (CalibTimeoutError, DamiaoOverloadError)
    READING_GAP_S: ClassVar[float] = math.inf
    """No bound on the time between two readings of a search (``SearchConfig.max_reading_gap_s``): robocal held up
    for less than the armed TIMEOUT left the motor under its last command (a target within ``MAX_LAG_RAD`` of the
    joint, a push at most the cap), so the reading after the gap is evidence like any other; held up for longer,
    the motor stopped itself (0xD) and the next reading, enable or re-read says so (:class:`DamiaoWatchdogError`)."""

    _mode_checked = False
    _ever_enabled = False
    on_zero: Callable[[str, str, float], None] | None = None
    """Told each state of this motor's zero in ``--write-zero`` (planned, storing, stored, unchanged, written) and
    the reading where it goes: the state folder's record (:mod:`robocal.workflows.motion.damiao_watchdog`)."""

    def position_range_rad(self) -> float:
        """The motor's PMAX (register 21 where it was read, else its model's: 12.5 rad on the OpenArm's)."""
        return float(self.bus.limits[self.name].p_max_rad)

    # ------------------------------------------------------------------------------------------ frames
    def _sample(self, st: MotorState, overload: bool = False) -> StopSample:
        d = self.direction
        s = StopSample(
            self.clock.now(), d * st.position_rad, d * st.velocity_rad_s, d * st.torque_nm, True, overload
        )
        self._q = s.q_rad
        return s

    def _command(self, target: MitTarget) -> MitCommand:
        """``target`` in the motor's frame."""
        d = self.direction
        p, v, kp, kd, t = target
        return MitCommand(d * p, d * v, kp, kd, d * t)

    def _exchange(self, target: MitTarget) -> StopSample:
        try:
            return self._sample(self.bus.mit(self.name, self._command(target)))
        except DamiaoOverloadError:
            return StopSample(self.clock.now(), self._q, ok=math.isfinite(self._q), overload=True)
        except DamiaoLostCommError as exc:
            self.enabled = False
            raise DamiaoWatchdogError(self._tripped(exc)) from None

    def _send_nowait(self, target: MitTarget) -> None:
        self.bus.send_mit(self.name, self._command(target))

    def _switch_on(self) -> StopSample:
        try:
            if not self._mode_checked:
                mode = int(self.bus.read_register(self.name, Register.CTRL_MODE))
                if mode != ControlMode.MIT:
                    raise DeviceError(
                        f"joint {self.name}: the motor is in control mode {mode} (CTRL_MODE, register 10), not MIT "
                        "(1); robocal does not change it: set it with openarm-can-cli or the Damiao tool"
                    )
                self._mode_checked = True
            self.arm_watchdog()
            st = self.bus.enable([self.name])[self.name]
        except CalibTimeoutError:
            return StopSample(self.clock.now(), math.nan, ok=False)
        except DamiaoLostCommError as exc:
            if not self._ever_enabled:
                raise  # found so (a previous run's host lost): not this run's
            raise DamiaoWatchdogError(self._tripped(exc)) from None  # tripped since this run last drove it
        self.enabled = self._ever_enabled = True
        self._last = MitTarget(0.0, 0.0, 0.0, self.kd, 0.0)  # damping only until the first command
        return self._sample(st)

    def _clear_fault(self) -> bool:
        """Clear an overload latch (0xE), the one state the search re-reads; any other error state is raised.

        The state is read before anything is cleared: a reread follows a lost reply as well as an overload, and a
        motor whose TIMEOUT tripped meanwhile (robocal held up past it: state 0xD, limp) must end the run as the
        fault it is (:class:`DamiaoWatchdogError`), not be cleared and driven on as if it had held its command.
        """
        try:
            code = self.bus.read_state(self.name, check=False).state
            if code == State.LOST_COMM:
                self.enabled = False
                raise DamiaoWatchdogError(self._tripped("state 0xD read before clearing a latch"))
            err = fault_error(code, self.name) if code != State.OVERLOAD else None
            if err is not None:
                raise err
            self.bus.clear_error(self.name)
        except CalibTimeoutError:
            return True
        except DamiaoOverloadError:
            pass  # still latched: the enable after it is ignored and the next reading says so again
        return False

    def _tripped(self, what: object) -> str:
        return (
            f"joint {self.name}: the motor reported communication lost (0xD): its TIMEOUT ({self.watchdog_s:g} s) "
            f"tripped because no frame reached it in time (robocal was held up or the bus dropped frames): {what}"
        )

    def _push_torque_nm(self, limit_nm: float) -> float:
        return min(limit_nm, self.cap_nm)

    def _read_watchdog(self) -> float:
        return float(self.bus.read_register(self.name, Register.TIMEOUT)) * TIMEOUT_UNIT_S

    def _write_watchdog(self, timeout_s: float) -> None:
        self.bus.write_register(self.name, Register.TIMEOUT, self.bus.watchdog_units(timeout_s))

    def _torque_off_nowait(self) -> None:
        self.bus.torque_off_nowait([self.name])

    def _torque_off(self) -> None:
        with suppress(Exception):
            self.bus.limp([self.name])
        with suppress(Exception):
            self.bus.disable([self.name])

    # ------------------------------------------------------------------------------------------ zeroing
    def settle_at(self, target_rad: float, duration_s: float, *, max_lag_rad: float = math.radians(0.5)) -> float:
        """Hold the joint at ``target_rad`` with a stiffer spring; the mean position over the second half.

        The spring is ``kp = cap / max_lag`` (the torque still at most the cap while the joint is within
        ``max_lag``), held for ``duration_s``. For storing a zero: the drive's own spring (``cap / 3°``) leaves
        friction a dead band of a few tenths of a degree; this one a sixth of it. The target must already be
        within ``max_lag`` (the joint was moved there).
        """
        kp = min(500.0, self.cap_nm / max_lag_rad)
        with self.lock:
            self._last = MitTarget(target_rad, 0.0, kp, max(self.kd, 0.02 * kp * 0.05), 0.0)
            qs = [self._mit(self._last).q_rad for _ in range(max(2, round(duration_s / self.period_s)))]
        half = [q for q in qs[len(qs) // 2 :] if math.isfinite(q)]
        return sum(half) / len(half) if half else math.nan

    def store_zero(self) -> float:
        """Make the joint's present position the motor's zero (one flash write).

        Limp, then openarm_can's sequence (disable, 0xFE, disable) through :meth:`~.bus.DamiaoBus.set_zero`.
        Returns the reading after it (joint frame, rad; ≈ 0 unless the joint moved once unpowered).
        """
        with self.lock:
            self.limp()
            st = self.bus.set_zero(self.name, confirm=True)
            self._q = self.direction * st.position_rad
            return self._q
