"""A Robstride motor as a joint driver of the automatic hard-stop calibration (MIT frames over python-can)."""

from __future__ import annotations

import math
from contextlib import suppress
from typing import Any

from ...core.motor_models import rated_motor_model
from ...core.stop_search import Command, StopSample
from ...errors import CalibTimeoutError, DeviceError
from ..clock import Clock

LIMIT_TORQUE = 0x700B
"""Robstride ``limit_torque`` parameter (f32, N·m; RAM until a type-22 save, which robocal never sends)."""
WATCHDOG_S = 0.5
"""The host-loss watchdog armed on every motor that moves: ``canTimeout`` so that a motor that hears no frame for
this long (a killed process, a pulled cable, a host held up) enters reset mode on its own."""
KEEPALIVE_S = 0.1
"""A motor enabled but not commanded (a joint holding its pose while another is searched) is sent its last
command again at least this often, so its watchdog only trips when robocal stops sending altogether."""
_ENABLED: dict[int, list[RobstrideJointDriver]] = {}
"""Enabled drivers per clock (the joints of one run): each frame a driver sends refreshes the quiet others."""

__all__ = [
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


class RobstrideJointDriver:
    """A Robstride motor driven with MIT frames (type 1) through :class:`~robocal.backends.robstride.RobstrideBus`.

    ``drive``/``hold``: position target with ``kp = cap / max_lag`` (scaled down for a lower limit) and a small
    ``kd``, feed-forward velocity, no feed-forward torque, so ``|τ| ≤ kp·max_lag + kd·|v_ref − v|`` (the cap plus
    a little damping). ``push``: ``kp = 0``, ``τ_ff = ±limit``, damping ``kd``. ``limp``: MIT ``(0, 0, 0, 0, 0)``
    then type 4 (stop). ``reread``: type 4 stop with fault clear, type 3 enable, a zero-torque MIT read. Angles
    are in the joint's identity frame ``s = direction·raw``. The firmware's ``limit_torque`` (0x700B, a RAM
    parameter: type 18, never saved to flash) is set to ``1.05·cap`` when the motor is first enabled, so a
    rebound or a control-period delay can never push harder than the cap + 5 %; :meth:`limp` writes the value
    read before back (a power cycle restores it too). Whatever the caller asks, the cap, ``limit_torque`` and every
    feed-forward torque stay within the hard ceiling of the motor model's rating (:attr:`ceiling_nm`, from the
    bus's model name and :mod:`robocal.core.motor_models`).

    Args:
        bus: The bus the motor is on.
        name: Joint (motor) name on that bus.
        direction: URDF direction ±1.
        cap_nm: Torque cap the gains are computed for.
        max_lag_rad: The largest lead of the target (``kp = cap/max_lag``).
        clock: Time source; :meth:`execute` lets ``period_s`` pass per command.
        period_s: Control period.
        kd: Damping gain, N·m·s/rad (default ``0.05·cap`` per rad/s: damping adds ≤ 5 % of the cap at 1 rad/s).
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
        self.lost_reply_s = lost_reply_s
        self.name = name
        self.direction = int(direction)
        spec = getattr(bus, "motors", {}).get(name)
        model = rated_motor_model(name, getattr(spec, "model", None))
        self.ceiling_nm = model.ceiling_nm
        """No torque asked of the motor is above this (the hard ceiling of its model's rated torque)."""
        cap_nm = min(float(cap_nm), self.ceiling_nm)
        self.cap_nm = cap_nm
        self.kp = cap_nm / max_lag_rad
        self.kd = 0.05 * cap_nm if kd is None else kd
        self.clock = clock
        self.period_s = period_s
        self.enabled = False
        self._last: tuple[float, float, float, float, float] = (0.0, 0.0, 0.0, self.kd, 0.0)
        self._q = math.nan
        self._saved_limit: float | None = None
        self._saved_watchdog_s: float | None = None
        self._last_tx_s = -math.inf

    def _sample(self, fb: Any) -> StopSample:
        d = self.direction
        if fb.faults & ROBSTRIDE_FATAL_BITS:
            raise DeviceError(f"joint {self.name}: motor fault bits {fb.faults:#04x}")
        if self.enabled and getattr(fb, "mode", 2) != 2:
            self.enabled = False
            raise RobstrideWatchdogError(
                f"joint {self.name}: the motor left run mode on its own (mode {fb.mode}): its CAN timeout "
                f"({WATCHDOG_S:g} s) stopped it because no frame reached it in time (robocal was held up or the "
                "bus dropped frames)"
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

    def _mit(self, cmd: tuple[float, float, float, float, float]) -> StopSample:
        d = self.direction
        p, v, kp, kd, t = cmd
        t = max(-self.ceiling_nm, min(self.ceiling_nm, t))
        t_send = self.clock.now()
        self._last_tx_s = t_send
        try:
            fb = self.bus.mit_command(self.name, d * p, d * v, kp, kd, d * t)
        except CalibTimeoutError:
            return self._lost(t_send)
        s = self._sample(fb)
        self._keep_others_alive(t_send)
        self.clock.sleep(self.period_s - (self.clock.now() - t_send))
        return s

    def _keep_others_alive(self, now_s: float) -> None:
        """Send the quiet enabled motors of this run their last command again (their watchdogs stay armed)."""
        for other in _ENABLED.get(id(self.clock), []):
            if other is not self and other.enabled and now_s - other._last_tx_s >= KEEPALIVE_S:
                other._last_tx_s = now_s
                d = other.direction
                p, v, kp, kd, t = other._last
                t = max(-other.ceiling_nm, min(other.ceiling_nm, t))
                with suppress(CalibTimeoutError):
                    other._sample(other.bus.mit_command(other.name, d * p, d * v, kp, kd, d * t))

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

    def _enable_timed(self) -> StopSample:
        t_send = self.clock.now()
        s = self._enable()
        return s if s.ok else self._lost(t_send)

    def _enable(self) -> StopSample:
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
        self._last = (
            0.0,
            0.0,
            0.0,
            self.kd,
            0.0,
        )  # damping only until the first command: enabling never moves
        return s

    def read(self) -> StopSample:
        """Read the joint, repeating the last command (enable first, with damping only, if needed)."""
        if not self.enabled:
            s = self._enable_timed()
            if not s.ok:
                return s
        return self._mit(self._last)

    def execute(self, cmd: Command) -> StopSample:
        """One MIT frame for ``cmd``; its feedback frame is the reading."""
        if cmd.action == "limp":
            self.limp()
            return StopSample(self.clock.now(), self._q, ok=math.isfinite(self._q))
        if not self.enabled:
            s = self._enable_timed()
            if not s.ok:
                return s
        if cmd.action == "reread":
            with suppress(CalibTimeoutError):
                self.bus.stop(self.name, clear_faults=True)
            self.enabled = False
            s = self._enable_timed()
            if not s.ok:
                return s
            return self._mit(self._last)
        if cmd.action == "push":
            sign = 1.0 if not math.isfinite(self._q) or cmd.q_target_rad >= self._q else -1.0
            self._last = (0.0, 0.0, 0.0, self.kd, sign * cmd.torque_limit_nm)
        else:
            kp = self.kp * min(1.0, cmd.torque_limit_nm / self.cap_nm)
            self._last = (cmd.q_target_rad, cmd.v_target_rad_s, kp, self.kd, 0.0)
        return self._mit(self._last)

    def arm_watchdog(self) -> None:
        """Arm the motor's host-loss watchdog (``canTimeout`` = :data:`WATCHDOG_S`) before it moves (once)."""
        arm = getattr(self.bus, "arm_watchdog", None)
        if self._saved_watchdog_s is None and arm is not None:
            self._saved_watchdog_s = float(arm(self.name, WATCHDOG_S))
        peers = _ENABLED.setdefault(id(self.clock), [])
        if self not in peers:
            peers.append(self)

    def disarm_watchdog(self) -> None:
        """Put ``canTimeout`` back as it was before :meth:`arm_watchdog`; never raises."""
        peers = _ENABLED.get(id(self.clock), [])
        if self in peers:
            peers.remove(self)
        if not peers:
            _ENABLED.pop(id(self.clock), None)
        if self._saved_watchdog_s is not None:
            with suppress(Exception):
                self.bus.disarm_watchdog(self.name, self._saved_watchdog_s)
                self._saved_watchdog_s = None

    def limp(self) -> None:
        """MIT zero torque, then type 4 stop (reset mode), the watchdog disarmed; never raises."""
        self._last = (0.0, 0.0, 0.0, 0.0, 0.0)
        with suppress(Exception):
            self.bus.mit_command(self.name, 0.0, 0.0, 0.0, 0.0, 0.0)
        with suppress(Exception):
            self.bus.stop(self.name)
        if self._saved_limit is not None:
            with suppress(Exception):
                self.bus.write_param(self.name, LIMIT_TORQUE, self._saved_limit)
                self._saved_limit = None
        self.disarm_watchdog()
        self.enabled = False
