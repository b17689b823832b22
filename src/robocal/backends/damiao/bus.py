"""``DamiaoBus``: one CAN channel of Damiao motors on python-can (classic CAN or CAN FD).

Each motor is named with its two ids and its model. At connect the bus reads every motor's PMAX / VMAX / TMAX
registers (21-23) and packs and unpacks MIT and state frames with them; with ``ranges="table"`` it uses the
model table (``tables.MODELS``) instead, and :attr:`DamiaoBus.range_sources` says so. Every state reply is
judged by :func:`~.protocol.check_state`, so a motor in an error state raises its named fault (exit 3); a
motor that stays silent raises :class:`~robocal.errors.CalibTimeoutError` naming it.

Read-only by default, like every robocal backend: refresh, register reads, disable, clear error and the limp MIT
frame ``(0, 0, 0, 0, 0)`` always work; enable, any other MIT frame and register writes are refused unless the
bus was opened with ``allow_motion=True`` (the guarded path does), and set zero and save also take
``confirm=True`` per call (they write the motor's flash, ~10 000 cycles).

Frame types: with ``fd=True`` the MIT, special and refresh frames go out FD-flagged (as LeRobot sends them);
register read / write / save frames always go out as classic CAN (openarm_can's CLI: "Config frames (0x7FF)
must be sent via Classic CAN"). Replies are matched by arbitration id (MST_ID); a register reply must also
repeat the motor's ESC_ID, the op and the register.
"""

from __future__ import annotations

import logging
import math
import threading
import time
from collections.abc import Iterable, Iterator, Mapping, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, Literal

from ...core.lifecycle import ClosesOnExit
from ...errors import CalibTimeoutError, DeviceError, ProtocolError, UsageError
from .. import reply_timeout_floor_s, require
from ..can_receive import LATE_FRAMES, OPEN_DEADLINE_S, asked_again, frames_until, open_within
from .protocol import (
    Frame,
    MitCommand,
    MotorState,
    check_state,
    clear_error_frame,
    decode_register_reply,
    decode_state,
    disable_frame,
    enable_frame,
    encode_mit_command,
    refresh_frame,
    register_read_frame,
    register_write_frame,
    save_frame,
    set_zero_frame,
    unpack_register_value,
)
from .tables import ID_MAX, OP_READ, OP_WRITE, RANGE_REGISTERS, MotorLimits, Register, model_limits

if TYPE_CHECKING:
    from ...core.profile import RobotProfile

__all__ = ["DEFAULT_TIMEOUT_S", "LIMP", "DamiaoBus", "DamiaoMotor", "motors_by_bus"]

log = logging.getLogger(__name__)

DEFAULT_TIMEOUT_S = 0.1
"""Default time to wait for one reply, s (LeRobot waits 1-10 ms and keeps a stale value; robocal raises)."""
LIMP = MitCommand(0.0, 0.0, 0.0, 0.0, 0.0)
"""The MIT frame that asks for no torque: the one MIT frame a read-only bus sends."""


@dataclass(frozen=True)
class DamiaoMotor:
    """A motor on a bus.

    Attributes:
        name: Name used in messages (usually the joint name).
        esc_id: The id it listens on (register ESC_ID; OpenArm joint n: 0x0n).
        mst_id: The id its replies carry (register MST_ID; OpenArm joint n: 0x1n).
        model: Model name (``"DM4310"``, ``"DM4340"``, ``"DM8009"``, ...; ``tables.MODELS``).
    """

    name: str
    esc_id: int
    mst_id: int
    model: str


def motors_by_bus(profile: RobotProfile, names: Iterable[str]) -> dict[str | None, list[DamiaoMotor]]:
    """Per profile bus (in the profile's order), the :class:`DamiaoMotor` of each joint in ``names``.

    Raises:
        UsageError: A named joint without the id, reply id or model a Damiao bus needs.
    """
    wanted = set(names)
    out: dict[str | None, list[DamiaoMotor]] = {}
    for j in profile.joints:
        if j.name not in wanted:
            continue
        if j.motor_id is None or j.reply_id is None or j.model is None:
            raise UsageError(f"profile {profile.name}: joint {j.name} needs id, reply_id and model for a Damiao bus")
        out.setdefault(j.bus, []).append(DamiaoMotor(j.name, j.motor_id, j.reply_id, j.model.upper()))
    return out


class DamiaoBus(ClosesOnExit):
    """Damiao motors on one CAN channel.

    Args:
        channel: python-can channel (``"can0"``; any name for ``virtual``).
        motors: The motors on the channel.
        interface: python-can interface (``"socketcan"``, ``"virtual"``, ``"socketcand"``, ...).
        fd: Open the channel for CAN FD and send MIT / special / refresh frames FD-flagged.
        ranges: ``"registers"``: read PMAX / VMAX / TMAX from each motor at connect; ``"table"``: assume the
            model table's (no frame is sent; :attr:`range_sources` records it).
        allow_motion: Allow enable, pushing MIT frames, register writes, set zero and save (the guarded path).
        timeout_s: Time to wait for each reply, s (at least ``$ROBOCAL_REPLY_TIMEOUT_MS``).
        bus: An already open python-can bus to use instead of opening one (not closed by :meth:`close`).
        bus_kwargs: More arguments for ``can.Bus`` (``bitrate``, ``data_bitrate``, ``host``, ``port``, ...).

    Raises:
        UsageError: A motor's ids or model are invalid or listed twice, or an unknown interface.
        DeviceError: The channel cannot be opened.
        CalibTimeoutError: A motor did not answer the range-register reads.
    """

    def __init__(
        self,
        channel: str,
        motors: Sequence[DamiaoMotor],
        *,
        interface: str = "socketcan",
        fd: bool = False,
        ranges: Literal["registers", "table"] = "registers",
        allow_motion: bool = False,
        timeout_s: float = DEFAULT_TIMEOUT_S,
        bus: Any = None,
        bus_kwargs: Mapping[str, Any] | None = None,
    ) -> None:
        if not timeout_s > 0:
            raise UsageError(f"Damiao bus {channel}: timeout {timeout_s} s must be > 0")
        if ranges not in ("registers", "table"):
            raise UsageError(f"Damiao bus {channel}: ranges {ranges!r}; expected 'registers' or 'table'")
        self.channel = channel
        self.interface = interface
        self.fd = bool(fd)
        self.allow_motion = bool(allow_motion)
        self.timeout_s = max(float(timeout_s), reply_timeout_floor_s())
        self.motors: dict[str, DamiaoMotor] = {}
        self._by_mst: dict[int, DamiaoMotor] = {}
        self.limits: dict[str, MotorLimits] = {}
        """Motor name → the ranges its frames are packed with."""
        self.range_sources: dict[str, str] = {}
        """Motor name → ``"registers"`` (read from the motor) or ``"table"`` (assumed from the model)."""
        used: set[int] = set()
        for m in motors:
            for what, cid in (("ESC_ID", m.esc_id), ("MST_ID", m.mst_id)):
                if not 0 <= cid <= ID_MAX or cid == 0x7FF:
                    raise UsageError(f"motor {m.name!r}: {what} {cid:#x} must be an 11-bit id below 0x7ff")
            if m.name in self.motors or m.esc_id in used or m.mst_id in used or m.esc_id == m.mst_id:
                raise UsageError(
                    f"Damiao bus {channel}: motor {m.name!r} (ESC_ID {m.esc_id:#x}, MST_ID {m.mst_id:#x}) "
                    "repeats a name or an id"
                )
            used |= {m.esc_id, m.mst_id}
            self.motors[m.name] = m
            self._by_mst[m.mst_id] = m
            self.limits[m.name] = model_limits(m.model)
            self.range_sources[m.name] = "table"
        self._can = require(
            "can",
            "the Damiao CAN backend",
            message="the Damiao CAN backend needs the Python package 'can': pip install 'robocal[damiao]'",
        )
        self._owns_bus = bus is None
        self._bus = bus
        self._send_lock = threading.Lock()  # the keep-alive thread sends too (send_mit)
        if bus is None:
            valid = sorted(getattr(self._can, "VALID_INTERFACES", ()))
            if valid and interface not in valid:
                raise UsageError(
                    f"CAN interface {interface!r} is unknown to python-can; expected one of {', '.join(valid)}"
                )
            kwargs = dict(bus_kwargs or {})
            if self.fd:
                kwargs["fd"] = True
            # in a worker with a deadline: python-can's socketcand client waits for a frozen server's greeting forever
            self._bus = open_within(
                OPEN_DEADLINE_S + self.timeout_s,
                lambda: self._can.Bus(channel=channel, interface=interface, receive_own_messages=False, **kwargs),
                f"CAN {interface}:{channel}",
            )
        if ranges == "registers":
            try:
                self.read_ranges()
            except BaseException:
                self.close()
                raise
        else:
            names = ", ".join(self.motors)
            log.warning(
                "Damiao bus %s: ranges assumed from the model table, not read from %s", channel, names
            )

    # ------------------------------------------------------------------------------------------ lifecycle
    def close(self) -> None:
        """Close the CAN channel (if this object opened it)."""
        if self._bus is not None and self._owns_bus:
            self._bus.shutdown()
        self._bus = None

    def _spec(self, motor: str) -> DamiaoMotor:
        if motor not in self.motors:
            raise UsageError(
                f"Damiao bus {self.channel}: no motor named {motor!r}; known: {', '.join(self.motors)}"
            )
        return self.motors[motor]

    def _label(self, m: DamiaoMotor) -> str:
        return f"{m.name!r} (ESC_ID {m.esc_id:#x}, MST_ID {m.mst_id:#x} on {self.interface}:{self.channel})"

    def _where(self, m: DamiaoMotor) -> str:
        return f"motor {self._label(m)}"

    def _gate(self, what: str, motor: DamiaoMotor, *, confirm: bool | None = None) -> None:
        if not self.allow_motion:
            raise UsageError(
                f"{self._where(motor)}: {what} refused: the bus is read-only (open it with allow_motion=True, "
                "as the guarded motion path does)"
            )
        if confirm is False:
            raise UsageError(f"{self._where(motor)}: {what} writes the motor's flash; it needs confirm=True")

    # ------------------------------------------------------------------------------------------ transport
    def _send(self, frame: Frame, *, fd: bool) -> None:
        if self._bus is None:
            raise DeviceError(f"Damiao bus {self.channel} is closed")
        arb, data = frame
        msg = self._can.Message(arbitration_id=arb, data=data, is_extended_id=False, is_fd=fd)
        try:
            with self._send_lock:
                self._bus.send(msg, timeout=self.timeout_s)
        except Exception as exc:
            raise DeviceError(f"CAN {self.interface}:{self.channel}: send failed ({exc})") from None

    def _drain(self) -> None:
        """Drop replies that came too late for an earlier request (they would answer the next one)."""
        for _ in range(LATE_FRAMES):
            if self._bus.recv(timeout=0.0) is None:
                return

    def _receive(self, deadline: float) -> Iterator[Any]:
        """Standard-id frames received before ``deadline`` (and the ones already queued when it passed)."""
        yield from frames_until(self._bus, deadline, extended=False, now=time.monotonic)

    def _exchange(
        self, frames: Mapping[str, Frame], *, fd: bool, accept: Mapping[str, tuple[int, int] | None]
    ) -> dict[str, bytes]:
        """Send one frame per motor and collect one reply from each (from its MST_ID).

        ``accept[name]`` is None for a state frame, or ``(op, rid)`` for a register reply (which must also name
        the motor's ESC_ID).
        """
        self._drain()
        for frame in frames.values():
            self._send(frame, fd=fd)
        got: dict[str, bytes] = {}
        want = {self.motors[n].mst_id: n for n in frames}
        for msg in self._receive(time.monotonic() + self.timeout_s):
            name = want.get(msg.arbitration_id)
            if name is None or name in got:
                continue
            data = bytes(msg.data)
            expect = accept[name]
            esc = self.motors[name].esc_id
            head = bytes([esc & 0xFF, esc >> 8])
            if expect is not None:
                if len(data) != 8 or data[:4] != head + bytes(expect):
                    continue  # a state frame (or a reply to something else) from the same motor
            elif data[:2] == head and data[2:3] in (b"\x33", b"\x55"):
                continue  # a late register reply (a state frame reads so only at −PMAX, the far end of its range)
            got[name] = data
            if len(got) == len(frames):
                break
        missing = [self._where(self.motors[n]) for n in frames if n not in got]
        if missing:
            raise CalibTimeoutError(f"no reply within {self.timeout_s:g} s from {', '.join(missing)}")
        return got

    def _states(self, frames: Mapping[str, Frame], *, check: bool) -> dict[str, MotorState]:
        got = self._exchange(frames, fd=self.fd, accept=dict.fromkeys(frames))
        out: dict[str, MotorState] = {}
        for name in frames:
            state = decode_state(got[name], self.limits[name])
            out[name] = check_state(state, self._label(self.motors[name])) if check else state
        return out

    def _names(self, motors: Iterable[str] | None) -> list[str]:
        names = list(self.motors) if motors is None else [self._spec(m).name for m in motors]
        if len(set(names)) != len(names):
            raise UsageError(f"Damiao bus {self.channel}: a motor is named twice in {names}")
        return names

    # ------------------------------------------------------------------------------------------- reading
    def refresh(self, motors: Iterable[str] | None = None, *, check: bool = True) -> dict[str, MotorState]:
        """Ask each motor (all by default) for a state frame (0x7FF, op 0xCC); motor name → state.

        Raises:
            DamiaoFaultError: ``check`` and a motor reports an error state (its subclass names the code).
        """
        names = self._names(motors)
        return self._states({n: refresh_frame(self.motors[n].esc_id) for n in names}, check=check)

    def read_state(self, motor: str, *, check: bool = True) -> MotorState:
        """One motor's state frame (:meth:`refresh`)."""
        return self.refresh([motor], check=check)[self._spec(motor).name]

    def read_register(self, motor: str, rid: int) -> float:
        """Register ``rid`` of ``motor`` (op 0x33)."""
        return self.read_register_many([motor], rid)[self._spec(motor).name]

    def read_register_many(self, motors: Iterable[str] | None, rid: int) -> dict[str, float]:
        """Register ``rid`` of several motors (all by default); motor name → value."""
        names = self._names(motors)
        frames = {n: register_read_frame(self.motors[n].esc_id, rid) for n in names}
        accept = dict.fromkeys(names, (OP_READ, int(rid)))  # a read changes nothing: asked again before naming one
        got = asked_again(lambda: self._exchange(frames, fd=False, accept=accept))
        return {n: decode_register_reply(got[n]).value for n in names}

    def read_ranges(self) -> dict[str, MotorLimits]:
        """Read PMAX / VMAX / TMAX (registers 21-23) of every motor and scale its frames with them.

        Raises:
            ProtocolError: A motor reports a range that is not a positive number.
        """
        values = {rid: self.read_register_many(None, rid) for rid in RANGE_REGISTERS}
        for name, spec in self.motors.items():
            p, v, t = (values[rid][name] for rid in RANGE_REGISTERS)
            if not all(math.isfinite(x) and x > 0 for x in (p, v, t)):
                raise ProtocolError(f"{self._where(spec)} reports ranges PMAX {p}, VMAX {v}, TMAX {t}")
            self.limits[name] = MotorLimits(spec.model, p, v, t, "read from the motor's registers 21-23")
            self.range_sources[name] = "registers"
        return dict(self.limits)

    def probe(self, motors: Iterable[str] | None = None) -> set[str]:
        """The motors (all by default) that answer a refresh within the timeout (nothing is judged)."""
        names = self._names(motors)
        frames = {n: refresh_frame(self.motors[n].esc_id) for n in names}
        try:
            return set(self._exchange(frames, fd=self.fd, accept=dict.fromkeys(names)))
        except CalibTimeoutError:
            return {n for n in names if self._answers(n)}

    def _answers(self, name: str) -> bool:
        try:
            self._exchange({name: refresh_frame(self.motors[name].esc_id)}, fd=self.fd, accept={name: None})
        except CalibTimeoutError:
            return False
        return True

    # --------------------------------------------------------------------------------------- safe commands
    def disable(self, motors: Iterable[str] | None = None) -> dict[str, MotorState]:
        """Switch motors off (0xFD; all by default). Always allowed; the replies are returned unjudged."""
        names = self._names(motors)
        return self._states({n: disable_frame(self.motors[n].esc_id) for n in names}, check=False)

    def clear_error(self, motor: str) -> MotorState:
        """Clear a latched error (0xFB), then refresh: the state after it, judged (the cause may remain)."""
        spec = self._spec(motor)
        self._send(clear_error_frame(spec.esc_id), fd=self.fd)
        return self.read_state(spec.name)

    def torque_off_nowait(self, motors: Iterable[str] | None = None) -> None:
        """The no-torque MIT frame, then disable (0xFD), to each motor (all by default); no reply awaited.

        The first frames of a limp: each motor's torque goes off as fast as the frames go out, whatever another
        motor's reply does (the replies are dropped by the next exchange). Always allowed. Every frame is tried;
        the first send that failed is raised afterwards.

        Raises:
            DeviceError: A frame could not be sent (a closed or lost channel).
        """
        names = self._names(motors)
        frames = [encode_mit_command(self.motors[n].esc_id, LIMP, self.limits[n]) for n in names]
        frames += [disable_frame(self.motors[n].esc_id) for n in names]
        failed: DeviceError | None = None
        for frame in frames:
            try:
                self._send(frame, fd=self.fd)
            except DeviceError as exc:
                failed = failed or exc
        if failed is not None:
            raise failed

    def limp(self, motors: Iterable[str] | None = None) -> dict[str, MotorState]:
        """The no-torque MIT frame ``(0, 0, 0, 0, 0)`` to each motor: a passive read, allowed read-only."""
        names = self._names(motors)
        return self.mit_many(dict.fromkeys(names, LIMP))

    # ---------------------------------------------------------------------------------- guarded commands
    def enable(self, motors: Iterable[str] | None = None) -> dict[str, MotorState]:
        """Switch motors on (0xFC; all by default); needs ``allow_motion``."""
        names = self._names(motors)
        for n in names:
            self._gate("enable", self.motors[n])
        return self._states({n: enable_frame(self.motors[n].esc_id) for n in names}, check=True)

    def mit(self, motor: str, command: MitCommand) -> MotorState:
        """One MIT command (motor frame) and the state it answers with."""
        return self.mit_many({motor: command})[self._spec(motor).name]

    def mit_many(self, commands: Mapping[str, MitCommand]) -> dict[str, MotorState]:
        """MIT commands to several motors, then every state reply; anything but :data:`LIMP` needs ``allow_motion``."""
        frames: dict[str, Frame] = {}
        for motor, cmd in commands.items():
            spec = self._spec(motor)
            if cmd != LIMP:
                self._gate("an MIT command that pushes", spec)
            frames[spec.name] = encode_mit_command(spec.esc_id, cmd, self.limits[spec.name])
        return self._states(frames, check=True)

    def send_mit(self, motor: str, command: MitCommand) -> None:
        """One MIT command, its state reply not awaited (needs ``allow_motion`` unless :data:`LIMP`).

        The keep-alive thread's frame; the next exchange drops the reply.
        """
        spec = self._spec(motor)
        if command != LIMP:
            self._gate("an MIT command that pushes", spec)
        self._send(encode_mit_command(spec.esc_id, command, self.limits[spec.name]), fd=self.fd)

    def write_register(self, motor: str, rid: int, value: float) -> float:
        """Write a register in RAM (op 0x55; lost at power-off unless saved); returns the value echoed.

        A write to PMAX / VMAX / TMAX rescales this bus's frames for the motor. Needs ``allow_motion``.

        Raises:
            ProtocolError: The echo carries another value (float32 rounding aside).
        """
        spec = self._spec(motor)
        self._gate(f"writing register {rid}", spec)
        frame = register_write_frame(spec.esc_id, rid, value)
        echo = decode_register_reply(
            self._exchange({spec.name: frame}, fd=False, accept={spec.name: (OP_WRITE, int(rid))})[spec.name]
        )
        sent = unpack_register_value(rid, frame[1][4:8])
        if echo.value != sent:
            raise ProtocolError(f"{self._where(spec)}: register {rid} echoed {echo.value}, written {sent}")
        if rid in RANGE_REGISTERS:
            lim = self.limits[spec.name]
            p, v, t = (
                echo.value if rid == r else old
                for r, old in zip(
                    RANGE_REGISTERS, (lim.p_max_rad, lim.v_max_rad_s, lim.t_max_nm), strict=True
                )
            )
            self.limits[spec.name] = MotorLimits(
                spec.model, p, v, t, "written to the motor's registers 21-23"
            )
        return echo.value

    def set_zero(self, motor: str, *, confirm: bool = False) -> MotorState:
        """Make the motor's current position its zero (0xFE), then refresh; needs ``allow_motion`` and ``confirm``.

        openarm_can disables the motor first (disable, 0xFE, disable); this does the same. Whether the motor
        answers 0xFE is not known, so the state returned is a refresh's.
        """
        spec = self._spec(motor)
        self._gate("set zero", spec, confirm=confirm)
        self.disable([spec.name])
        self._send(set_zero_frame(spec.esc_id), fd=self.fd)
        self.disable([spec.name])
        return self.read_state(spec.name)

    def save(self, motor: str, *, confirm: bool = False) -> None:
        """Save every register to flash (op 0xAA; the motor is disabled first, as openarm_can does).

        Needs ``allow_motion`` and ``confirm``. No source says the motor answers; a refresh afterwards checks
        it still does.
        """
        spec = self._spec(motor)
        self._gate("save", spec, confirm=confirm)
        self.disable([spec.name])
        self._send(save_frame(spec.esc_id), fd=False)
        self.read_state(spec.name)

    def watchdog_units(self, timeout_s: float) -> int:
        """TIMEOUT register units (50 µs) for ``timeout_s`` (0: off)."""
        if not (math.isfinite(timeout_s) and timeout_s >= 0):
            raise UsageError(f"Damiao TIMEOUT {timeout_s} s: expected a number of seconds >= 0")
        return round(timeout_s / 50e-6)

    def arm_watchdog(self, motor: str, timeout_s: float) -> float:
        """Set TIMEOUT (register 9, RAM; never saved by robocal): no frame for ``timeout_s`` → 0xD and limp.

        Returns:
            The TIMEOUT before, s (for :meth:`disarm_watchdog`).
        """
        before = self.read_register(motor, Register.TIMEOUT) * 50e-6
        self.write_register(motor, Register.TIMEOUT, self.watchdog_units(timeout_s))
        return before

    def disarm_watchdog(self, motor: str, timeout_s: float = 0.0) -> None:
        """Put TIMEOUT back (default 0: off, assumed to be the factory setting)."""
        self.write_register(motor, Register.TIMEOUT, self.watchdog_units(timeout_s))
