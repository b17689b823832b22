"""A Damiao motor as a joint driver of the automatic hard-stop calibration (MIT frames through ``DamiaoBus``).

The search's commands (``drive``, ``push``, ``reread``, ``hold``, ``limp``) as MIT frames with a torque cap, the
way :class:`~robocal.backends.robstride.joint_driver.RobstrideJointDriver` drives a Robstride motor. The bus must be
opened with ``allow_motion=True`` (the guarded path: ``robocal sweep --auto`` enters the motion guard first).
Nothing is written to a motor's flash: the host-loss watchdog (TIMEOUT, register 9) is a RAM write put back by
:meth:`DamiaoJointDriver.limp`, and the motor must already be in MIT mode (CTRL_MODE 1, which LeRobot and
openarm_can also assume; robocal reads it and refuses otherwise, it never changes it).
"""

from __future__ import annotations

import math
import threading
from collections.abc import Callable
from contextlib import suppress
from typing import Any

from ...core.motor_models import rated_motor_model
from ...core.stop_search import Command, StopSample
from ...errors import CalibTimeoutError, DeviceError
from ..clock import Clock, MonotonicClock
from ..mit_keepalive import KEEPALIVE_S, WATCHDOG_MIN_S, forget, peers_of, watchdog_for
from .faults import DamiaoLostCommError, DamiaoOverloadError
from .protocol import MitCommand, MotorState
from .tables import ControlMode, Register

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


class DamiaoJointDriver:
    """A Damiao motor driven with MIT frames through :class:`~robocal.backends.damiao.bus.DamiaoBus`.

    ``drive``/``hold``: position target with ``kp = cap / max_lag`` (scaled down for a lower limit), ``kd`` and the
    feed-forward velocity, no feed-forward torque, so ``|τ| ≤ kp·max_lag + kd·|v_ref − v|`` (the cap plus a little
    damping). ``push``: ``kp = 0``, ``τ_ff = ±limit``, damping ``kd``. ``limp``: the zero-torque MIT frame, then
    disable (0xFD), TIMEOUT put back. ``reread``: clear error (0xFB), enable (0xFC), the last command again.
    Angles are in the joint's frame ``s = direction·reading`` (the reading is relative to the motor's stored zero).
    An overload state (0xE) is suspect evidence (the search re-reads); every other error state ends the run.
    Whatever the caller asks, the cap and every feed-forward torque stay within the hard ceiling of the motor
    model's rating (:attr:`ceiling_nm`).

    Args:
        bus: The bus the motor is on (opened with ``allow_motion=True``).
        name: Motor name on that bus.
        direction: Axis direction ±1.
        cap_nm: Torque cap the gains are computed for.
        max_lag_rad: The largest lead of the target (``kp = cap/max_lag``).
        clock: Time source; :meth:`execute` lets ``period_s`` pass per command.
        period_s: Control period.
        kd: Damping gain, N·m·s/rad (default ``0.05·cap`` per rad/s).
        lost_reply_s: How long a lost reply takes on the hardware (moves a simulated clock on by it).

    Raises:
        UsageError: The reply wait needs a watchdog longer than robocal arms (before anything is sent).
    """

    def __init__(
        self,
        bus: Any,
        name: str,
        direction: int,
        cap_nm: float,
        max_lag_rad: float,
        clock: Clock,
        *,
        period_s: float = 0.01,
        kd: float | None = None,
        lost_reply_s: float | None = None,
    ) -> None:
        self.bus = bus
        self.name = name
        self.direction = int(direction)
        spec = getattr(bus, "motors", {}).get(name)
        model = rated_motor_model(name, getattr(spec, "model", None))
        self.ceiling_nm = model.ceiling_nm
        """No torque asked of the motor is above this (the hard ceiling of its model's rated torque)."""
        self.cap_nm = min(float(cap_nm), self.ceiling_nm)
        self.kp = self.cap_nm / max_lag_rad
        self.kd = 0.05 * self.cap_nm if kd is None else kd
        self.clock = clock
        self.period_s = period_s
        self.lost_reply_s = lost_reply_s
        self.enabled = False
        self._last = MitCommand(0.0, 0.0, 0.0, self.kd, 0.0)
        self._q = math.nan
        self._saved_watchdog_s: float | None = None
        self._mode_checked = False
        self.last_tx_s = -math.inf
        """When this driver last sent its motor a frame (clock seconds)."""
        self.last_keepalive_s = -math.inf
        """When the independent keep-alive last did (``time.monotonic``)."""
        self.lock = threading.RLock()
        """Held by every exchange of this driver; the independent keep-alive skips the motor meanwhile."""
        self.watchdog_s = watchdog_for(self.reply_wait_s())
        """TIMEOUT armed on the motor, s: over twice the longest reply wait."""
        self.on_watchdog: Callable[[str, float | None], None] | None = None
        """Told before TIMEOUT is armed (the value it had, s) and after it is put back (None): the state folder's
        record of what a killed run leaves armed (:mod:`robocal.workflows.autocal.damiao_watchdog`)."""

    def reply_wait_s(self) -> float:
        """The longest one exchange may wait for its reply, on this driver's clock, s.

        ``lost_reply_s`` when given; otherwise the bus's reply timeout on the wall clock, and 0 on a simulated
        clock (an exchange there takes no simulated time).
        """
        if self.lost_reply_s is not None:
            return float(self.lost_reply_s)
        return float(getattr(self.bus, "timeout_s", 0.0)) if isinstance(self.clock, MonotonicClock) else 0.0

    def _peers(self) -> Any:
        return peers_of(self.clock)

    # ------------------------------------------------------------------------------------------ frames
    def _sample(self, st: MotorState, overload: bool = False) -> StopSample:
        d = self.direction
        s = StopSample(
            self.clock.now(), d * st.position_rad, d * st.velocity_rad_s, d * st.torque_nm, True, overload
        )
        self._q = s.q_rad
        return s

    def _send(self, cmd: MitCommand) -> MotorState:
        """The MIT frame in the motor's frame (torque clamped to the ceiling)."""
        d = self.direction
        t = max(-self.ceiling_nm, min(self.ceiling_nm, cmd.torque_nm))
        return self.bus.mit(  # type: ignore[no-any-return]
            self.name, MitCommand(d * cmd.position_rad, d * cmd.velocity_rad_s, cmd.kp, cmd.kd, d * t)
        )

    def _mit(self, cmd: MitCommand) -> StopSample:
        t_send = self.clock.now()
        self.last_tx_s = t_send
        self._peers().beat()
        try:
            s = self._sample(self._send(cmd))
        except CalibTimeoutError:
            return self._lost(t_send)
        except DamiaoOverloadError:
            s = StopSample(self.clock.now(), self._q, ok=math.isfinite(self._q), overload=True)
        except DamiaoLostCommError as exc:
            self.enabled = False
            raise DamiaoWatchdogError(
                f"joint {self.name}: the motor reported communication lost (0xD): its TIMEOUT ({self.watchdog_s:g} s) "
                f"tripped because no frame reached it in time (robocal was held up or the bus dropped frames): {exc}"
            ) from None
        self._keep_others_alive(t_send)
        self.clock.sleep(self.period_s - (self.clock.now() - t_send))
        return s

    def _keep_others_alive(self, now_s: float) -> None:
        """Send the quiet enabled motors of this run their last command again (their watchdogs stay armed)."""
        for other in list(self._peers().members):
            if other is not self and other.enabled and now_s - other.last_tx_s >= KEEPALIVE_S:
                with other.lock:
                    other.last_tx_s = now_s
                    with suppress(CalibTimeoutError, DamiaoOverloadError):
                        other._sample(other._send(other._last))

    def resend_nowait(self) -> None:
        """The last command again, its reply not awaited (the independent keep-alive's frame)."""
        d = self.direction
        cmd = self._last
        t = max(-self.ceiling_nm, min(self.ceiling_nm, cmd.torque_nm))
        self.bus.send_mit(
            self.name, MitCommand(d * cmd.position_rad, d * cmd.velocity_rad_s, cmd.kp, cmd.kd, d * t)
        )

    def _lost(self, t_send: float) -> StopSample:
        """A reply that did not come: the exchange lasted the bus's reply timeout (a simulated clock moves on)."""
        timeout_s = (
            self.lost_reply_s if self.lost_reply_s is not None else float(getattr(self.bus, "timeout_s", 0.0))
        )
        self.clock.sleep(max(self.period_s, timeout_s) - (self.clock.now() - t_send))
        return StopSample(self.clock.now(), math.nan, ok=False)

    def _enable(self) -> StopSample:
        t_send = self.clock.now()
        self._peers().beat()
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
            return self._lost(t_send)
        self.enabled = True
        self._last = MitCommand(0.0, 0.0, 0.0, self.kd, 0.0)  # damping only until the first command
        return self._sample(st)

    # ------------------------------------------------------------------------------------------ JointDriver
    def read(self) -> StopSample:
        """Read the joint, repeating the last command (enable first, with damping only, if needed)."""
        with self.lock:
            return self._read()

    def _read(self) -> StopSample:
        if not self.enabled:
            s = self._enable()
            if not s.ok:
                return s
        return self._mit(self._last)

    def execute(self, cmd: Command) -> StopSample:
        """One MIT frame for ``cmd``; its state reply is the reading."""
        with self.lock:
            return self._execute(cmd)

    def _execute(self, cmd: Command) -> StopSample:
        if cmd.action == "limp":
            self.limp()
            return StopSample(self.clock.now(), self._q, ok=math.isfinite(self._q))
        if not self.enabled:
            s = self._enable()
            if not s.ok:
                return s
        if cmd.action == "reread":
            t_send = self.clock.now()
            self._peers().beat()
            try:
                self.bus.clear_error(self.name)
            except CalibTimeoutError:
                return self._lost(t_send)
            except DamiaoOverloadError:
                pass  # still latched: the enable below is ignored and the next reading says so again
            self.enabled = False
            s = self._enable()
            if not s.ok:
                return s
            return self._mit(self._last)
        if cmd.action == "push":
            sign = 1.0 if not math.isfinite(self._q) or cmd.q_target_rad >= self._q else -1.0
            self._last = MitCommand(0.0, 0.0, 0.0, self.kd, sign * min(cmd.torque_limit_nm, self.cap_nm))
        else:
            kp = self.kp * min(1.0, cmd.torque_limit_nm / self.cap_nm)
            self._last = MitCommand(cmd.q_target_rad, cmd.v_target_rad_s, kp, self.kd, 0.0)
        return self._mit(self._last)

    def arm_watchdog(self) -> None:
        """Arm the motor's host-loss watchdog (TIMEOUT = :attr:`watchdog_s`, RAM) before it moves (once).

        The motor joins its run's keep-alive (on the wall clock, the independent thread starts with the first).
        """
        if self._saved_watchdog_s is None:
            before_s = float(self.bus.read_register(self.name, Register.TIMEOUT)) * TIMEOUT_UNIT_S
            if self.on_watchdog is not None:
                self.on_watchdog(self.name, before_s)  # recorded before the write: a kill after it leaves the record
            self.bus.write_register(self.name, Register.TIMEOUT, self.bus.watchdog_units(self.watchdog_s))
            self._saved_watchdog_s = before_s
        wait = self.reply_wait_s()
        self._peers().add(
            self, wall_clock=isinstance(self.clock, MonotonicClock), stall_s=max(2.0 * wait, wait + 0.25)
        )

    def disarm_watchdog(self) -> None:
        """Put TIMEOUT back as it was before :meth:`arm_watchdog`; never raises."""
        run = peers_of(self.clock, create=False)
        if run is not None and run.remove(self):
            forget(self.clock)
        if self._saved_watchdog_s is not None:
            with suppress(Exception):
                self.bus.disarm_watchdog(self.name, self._saved_watchdog_s)
                self._saved_watchdog_s = None
                if self.on_watchdog is not None:
                    self.on_watchdog(self.name, None)

    def settle_at(self, target_rad: float, duration_s: float, *, max_lag_rad: float = math.radians(0.5)) -> float:
        """Hold the joint at ``target_rad`` with a stiffer spring; the mean position over the second half.

        The spring is ``kp = cap / max_lag`` (the torque still at most the cap while the joint is within
        ``max_lag``), held for ``duration_s``. For storing a zero: the drive's own spring (``cap / 3°``) leaves friction a dead band of a few tenths of a
        degree; this one a sixth of it. The target must already be within ``max_lag`` (the joint was moved there).
        """
        kp = min(500.0, self.cap_nm / max_lag_rad)
        with self.lock:
            self._last = MitCommand(target_rad, 0.0, kp, max(self.kd, 0.02 * kp * 0.05), 0.0)
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

    def limp(self) -> None:
        """The zero-torque MIT frame, disable (0xFD), the watchdog disarmed; never raises."""
        with self.lock:
            self._last = MitCommand(0.0, 0.0, 0.0, 0.0, 0.0)
            with suppress(Exception):
                self.bus.limp([self.name])
            with suppress(Exception):
                self.bus.disable([self.name])
            self.disarm_watchdog()
            self.enabled = False
