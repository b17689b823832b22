"""The MIT-mode CAN motor as a joint driver of the automatic hard-stop calibration: what every such vendor shares.

A CAN motor in MIT mode takes ``(q_ref, dq_ref, kp, kd, τ_ff)`` per frame and answers with its position, velocity
and torque. The stop search's commands map onto it the same way for every vendor
(:class:`MitJointDriver`): ``drive``/``hold`` a position target with ``kp = cap / max_lag`` (scaled down for a lower
limit), damping ``kd`` and the feed-forward velocity, no feed-forward torque, so ``|τ| ≤ kp·max_lag + kd·|v_ref −
v|`` (the cap plus a little damping); ``push`` ``kp = 0`` with ``τ_ff = ±limit``; ``limp`` the vendor's torque-off
and the watchdog put back; ``reread`` the vendor's fault clear, enable and the last command again. Angles are in
the joint's frame ``s = direction·reading``. Whatever the caller asks, every feed-forward torque stays within the
hard ceiling of the motor model's rating (:attr:`MitJointDriver.ceiling_nm`). The enabled motors of one run keep
each other alive (:mod:`robocal.backends.mit_keepalive`).

A vendor's driver (``backends/<vendor>/joint_driver.py``) is a small adapter: how a frame goes out and what its
reply says (:meth:`MitJointDriver._exchange`, :meth:`MitJointDriver._state_sample`), how a motor is switched on,
cleared and made limp, how its watchdog is armed, and its constants as class attributes (:attr:`MAX_LAG_RAD`,
:attr:`WATCHDOG_S`, ...), which the workflows read from the class they get through the vendor registry.
"""

from __future__ import annotations

import math
import threading
from collections.abc import Callable
from contextlib import suppress
from typing import Any, ClassVar, NamedTuple

from ..core.motor_models import rated_motor_model
from ..core.stop_search import Command, StopSample
from ..errors import CalibTimeoutError
from .clock import Clock, MonotonicClock
from .mit_keepalive import KEEPALIVE_S, WATCHDOG_MIN_S, RunPeers, forget, peers_of, watchdog_for

__all__ = ["MitJointDriver", "MitTarget"]


class MitTarget(NamedTuple):
    """One MIT command in the joint's frame (what the driver sends again to keep a motor alive)."""

    position_rad: float
    velocity_rad_s: float
    kp: float
    kd: float
    torque_nm: float


class MitJointDriver:
    """The shared body of an MIT-mode CAN motor's joint driver (see the module docstring).

    Args:
        bus: The bus the motor is on (opened for motion).
        name: Motor (joint) name on that bus.
        direction: Axis direction ±1.
        cap_nm: Torque cap the gains are computed for.
        max_lag_rad: The largest lead of the target (``kp = cap/max_lag``).
        clock: Time source; :meth:`execute` lets ``period_s`` pass per command.
        period_s: Control period.
        kd: Damping gain, N·m·s/rad (default ``0.05·cap`` per rad/s: damping adds ≤ 5 % of the cap at 1 rad/s).
        lost_reply_s: How long a lost reply takes on the hardware (moves a simulated clock on by it).

    Raises:
        UsageError: The reply wait needs a watchdog longer than robocal arms (vendors whose watchdog follows the
            reply wait; before anything is sent).
    """

    MAX_LAG_RAD: ClassVar[float] = math.radians(3.0)
    """The position target leads the joint by at most this: ``kp = cap / 3°`` (``sweep --auto``, its sim)."""
    WATCHDOG_S: ClassVar[float] = WATCHDOG_MIN_S
    """The host-loss watchdog armed on every motor that moves when replies are quick."""
    WATCHDOG_FOLLOWS_REPLY_WAIT: ClassVar[bool] = False
    """Arm ``watchdog_for(reply wait)`` (over twice the wait; refused over 2 s) instead of :attr:`WATCHDOG_S`."""
    KEEPALIVE_THREAD: ClassVar[bool] = False
    """On the wall clock, also keep the run's idle motors alive from a thread (the bus needs ``send_mit``)."""
    KEEPALIVE_IGNORES: ClassVar[tuple[type[BaseException], ...]] = (CalibTimeoutError,)
    """What an inline keep-alive's reply may raise without ending the run."""

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
        self.lost_reply_s = lost_reply_s
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
        self.enabled = False
        self._last = MitTarget(0.0, 0.0, 0.0, self.kd, 0.0)
        self._q = math.nan
        self._saved_watchdog_s: float | None = None
        self._armed = False  # the armed watchdog time is confirmed written
        self.last_tx_s = -math.inf
        """When this driver last sent its motor a frame (clock seconds)."""
        self.last_keepalive_s = -math.inf
        """When the independent keep-alive last did (``time.monotonic``)."""
        self.lock = threading.RLock()
        """Held by every exchange of this driver; the independent keep-alive skips the motor meanwhile."""
        self.watchdog_s = watchdog_for(self.reply_wait_s()) if self.WATCHDOG_FOLLOWS_REPLY_WAIT else self.WATCHDOG_S
        """The host-loss watchdog armed on the motor, s."""
        self.on_watchdog: Callable[[str, float | None], None] | None = None
        """Told before the watchdog is armed (the value it had, s) and after it is put back (None): the state
        folder's record of what a killed run leaves armed (:mod:`robocal.workflows.motion.damiao_watchdog`)."""

    POSITION_BITS: ClassVar[int] = 16
    """Width of the position field of the MIT reply, which spans ``±position_range_rad()``."""

    def position_count_rad(self) -> float:
        """One count of the position reading: ``2·P_MAX / (2^bits − 1)`` of the reply's position field."""
        return 2.0 * self.position_range_rad() / ((1 << self.POSITION_BITS) - 1)

    # ------------------------------------------------------------------------------------------ vendor
    def position_range_rad(self) -> float:
        """``P_MAX``: the reply's position field spans ``±P_MAX`` rad (the vendor's, per motor)."""
        raise NotImplementedError

    def _exchange(self, target: MitTarget) -> StopSample:
        """Send ``target`` (joint frame, torque already within the ceiling) and judge the reply (the vendor's).

        Raises:
            CalibTimeoutError: No reply in time.
        """
        raise NotImplementedError

    def _send_nowait(self, target: MitTarget) -> None:
        """Send ``target`` without waiting for the reply (the vendor's; only with :attr:`KEEPALIVE_THREAD`)."""
        raise NotImplementedError

    def _switch_on(self) -> StopSample:
        """Enable the motor (checks, torque limit, watchdog armed first); not ok when it did not answer."""
        raise NotImplementedError

    def _clear_fault(self) -> bool:
        """``reread``: clear a latched fault (the motor is enabled again after it); True when the reply was lost."""
        raise NotImplementedError

    def _read_watchdog(self) -> float | None:
        """The motor's watchdog time now, s (None: the bus has no watchdog)."""
        raise NotImplementedError

    def _write_watchdog(self, timeout_s: float) -> None:
        """Write the motor's watchdog time (RAM), s."""
        raise NotImplementedError

    def _torque_off(self) -> None:
        """The vendor's torque-off frames and anything else put back on limp; never raises."""
        raise NotImplementedError

    def _torque_off_nowait(self) -> None:
        """The vendor's torque-off frames sent without awaiting a reply (may raise; none by default)."""

    def _push_torque_nm(self, limit_nm: float) -> float:
        """The feed-forward torque of a push asking for ``limit_nm`` (before the ceiling clamp)."""
        return limit_nm

    # ------------------------------------------------------------------------------------------ frames
    def reply_wait_s(self) -> float:
        """The longest one exchange may wait for its reply, on this driver's clock, s.

        ``lost_reply_s`` when given; otherwise the bus's reply timeout on the wall clock, and 0 on a simulated
        clock (an exchange there takes no simulated time).
        """
        if self.lost_reply_s is not None:
            return float(self.lost_reply_s)
        return float(getattr(self.bus, "timeout_s", 0.0)) if isinstance(self.clock, MonotonicClock) else 0.0

    def _peers(self) -> RunPeers:
        run = peers_of(self.clock)
        assert run is not None
        return run

    def _clamped(self, target: MitTarget) -> MitTarget:
        t = max(-self.ceiling_nm, min(self.ceiling_nm, target.torque_nm))
        return target._replace(torque_nm=t)

    def _mit(self, target: MitTarget) -> StopSample:
        t_send = self.clock.now()
        self.last_tx_s = t_send
        self._peers().beat()
        try:
            s = self._exchange(self._clamped(target))
        except CalibTimeoutError:
            return self._lost(t_send)
        self._keep_others_alive(t_send)
        self.clock.sleep(self.period_s - (self.clock.now() - t_send))
        return s

    def _keep_others_alive(self, now_s: float) -> None:
        """Send the quiet enabled motors of this run their last command again (their watchdogs stay armed)."""
        for other in list(self._peers().members):
            if other is not self and other.enabled and now_s - other.last_tx_s >= KEEPALIVE_S:
                assert isinstance(other, MitJointDriver)
                with other.lock:
                    other.last_tx_s = now_s
                    with suppress(*other.KEEPALIVE_IGNORES):
                        other._exchange(other._clamped(other._last))

    def resend_nowait(self) -> None:
        """The last command again, its reply not awaited (the independent keep-alive's frame)."""
        self._send_nowait(self._clamped(self._last))

    def _lost(self, t_send: float) -> StopSample:
        """A reply that did not come: the exchange lasted the bus's reply timeout.

        On hardware that time has passed already; a simulated clock is moved on by it (``lost_reply_s``: the
        hardware's timeout), so time bounds count lost replies as they do on hardware.
        """
        timeout_s = (
            self.lost_reply_s if self.lost_reply_s is not None else float(getattr(self.bus, "timeout_s", 0.0))
        )
        self.clock.sleep(max(self.period_s, timeout_s) - (self.clock.now() - t_send))
        return StopSample(self.clock.now(), math.nan, ok=False)

    def _enable(self) -> StopSample:
        t_send = self.clock.now()
        self._peers().beat()
        s = self._switch_on()
        return s if s.ok else self._lost(t_send)

    # ------------------------------------------------------------------------------------------ JointDriver
    def read(self) -> StopSample:
        """Read the joint, repeating the last command (enable first, with damping only, if needed)."""
        with self.lock:
            if not self.enabled:
                s = self._enable()
                if not s.ok:
                    return s
            return self._mit(self._last)

    def execute(self, cmd: Command) -> StopSample:
        """One MIT frame for ``cmd``; its reply is the reading."""
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
            if self._clear_fault():
                return self._lost(t_send)
            self.enabled = False
            s = self._enable()
            if not s.ok:
                return s
            return self._mit(self._last)
        if cmd.action == "push":
            sign = 1.0 if not math.isfinite(self._q) or cmd.q_target_rad >= self._q else -1.0
            self._last = MitTarget(0.0, 0.0, 0.0, self.kd, sign * self._push_torque_nm(cmd.torque_limit_nm))
        else:
            kp = self.kp * min(1.0, cmd.torque_limit_nm / self.cap_nm)
            self._last = MitTarget(cmd.q_target_rad, cmd.v_target_rad_s, kp, self.kd, 0.0)
        return self._mit(self._last)

    def arm_watchdog(self) -> None:
        """Arm the motor's host-loss watchdog (:attr:`watchdog_s`) before it moves (once).

        The motor joins the run's keep-alive (on the wall clock the independent thread starts with the first, where
        the vendor has it).
        """
        if not self._armed:
            if self._saved_watchdog_s is None:  # the value before robocal armed it, kept until it is put back
                self._saved_watchdog_s = self._read_watchdog()
                if self._saved_watchdog_s is not None and self.on_watchdog is not None:
                    self.on_watchdog(self.name, self._saved_watchdog_s)  # before the write: a kill after it
            if self._saved_watchdog_s is not None:
                # a write whose echo is lost may have armed it all the same: the value kept above stays the one
                # put back, and the write is repeated before the next motion until one is confirmed
                self._write_watchdog(self.watchdog_s)
                self._armed = True
        wait = self.reply_wait_s()
        self._peers().add(
            self,
            wall_clock=self.KEEPALIVE_THREAD and isinstance(self.clock, MonotonicClock),
            stall_s=max(2.0 * wait, wait + 0.25),
        )

    def disarm_watchdog(self) -> None:
        """Put the watchdog back as it was before :meth:`arm_watchdog`; never raises."""
        run = peers_of(self.clock, create=False)
        if run is not None and run.remove(self):
            forget(self.clock)
        if self._saved_watchdog_s is not None:
            self._armed = False  # whatever this write does, arm again before the next motion
            with suppress(Exception):
                self._write_watchdog(self._saved_watchdog_s)
                self._saved_watchdog_s = None
                if self.on_watchdog is not None:
                    self.on_watchdog(self.name, None)

    def torque_off_nowait(self) -> None:
        """The vendor's torque-off frames at once, no reply awaited and no lock waited for; never raises.

        What :func:`robocal.workflows.autocal.model.limp_all` sends every enabled motor before the confirmed
        :meth:`limp` of any: one motor's lost or late reply (or the state file written when its watchdog is put
        back) no longer holds back another motor's torque-off (issue 26: every motor limp within 100 ms). The
        last command becomes the no-torque one, so a keep-alive sent meanwhile pushes nothing.
        """
        self._last = MitTarget(0.0, 0.0, 0.0, 0.0, 0.0)
        with suppress(Exception):
            self._torque_off_nowait()

    def limp(self) -> None:
        """The vendor's torque-off, the watchdog put back; never raises."""
        with self.lock:
            self._last = MitTarget(0.0, 0.0, 0.0, 0.0, 0.0)
            self._torque_off()
            self.disarm_watchdog()
            self.enabled = False
