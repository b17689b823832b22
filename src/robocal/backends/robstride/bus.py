"""``RobstrideBus``: one CAN channel of Robstride motors on python-can.

Every request waits for its reply with a timeout; a motor that stays silent is named in the
:class:`~robocal.errors.CalibTimeoutError`. The calibration path is passive: :meth:`RobstrideBus.zero_torque`
sends the MIT command ``(0, 0, 0, 0, 0)`` (no torque, no gains) and reads the feedback; nothing moves a joint.
:meth:`RobstrideBus.set_zero` (type 6) and :meth:`RobstrideBus.save` (type 22) only run when called explicitly
with ``confirm=True``.
"""

from __future__ import annotations

import time
from collections.abc import Iterable, Iterator, Mapping, Sequence
from dataclasses import dataclass
from typing import Any

from ...core.lifecycle import ClosesOnExit
from ...errors import CalibTimeoutError, DeviceError, ProtocolError, UsageError
from .. import reply_timeout_floor_s, require
from ..can_receive import LATE_FRAMES, frames_until, open_within
from ..can_receive import OPEN_DEADLINE_S as _OPEN_DEADLINE_S
from .protocol import (
    DEFAULT_HOST_ID,
    FIRMWARE_QUERY,
    SAVE_PAYLOAD,
    CommType,
    Feedback,
    ModelLimits,
    Param,
    decode_feedback,
    decode_firmware_reply,
    decode_param_reply,
    encode_mit_command,
    encode_param_read,
    encode_param_write,
    make_id,
    model_limits,
    split_id,
)

__all__ = ["CAN_TIMEOUT_UNITS_PER_S", "MotorSpec", "RobstrideBus"]

OPEN_DEADLINE_S = _OPEN_DEADLINE_S
"""Opening a CAN channel gives up after this plus the reply timeout (:func:`~robocal.backends.can_receive.open_within`)."""


DEFAULT_TIMEOUT_S = 0.1
"""Default time to wait for one reply (s)."""


CAN_TIMEOUT_UNITS_PER_S = 20000
"""``canTimeout`` (0x7028) units per second (the manual: "20000 is 1s"; 0 off)."""


@dataclass(frozen=True)
class MotorSpec:
    """A motor on a bus.

    Attributes:
        name: Name used in messages (usually the joint name).
        can_id: Motor CAN id, 1…127.
        model: Model name (``"rs-00"`` …).
    """

    name: str
    can_id: int
    model: str = "rs-00"


class RobstrideBus(ClosesOnExit):
    """Robstride motors on one CAN channel.

    Args:
        channel: python-can channel (``"can0"``; any name for ``virtual``).
        motors: The motors on the channel.
        interface: python-can interface (``"socketcan"``, ``"virtual"``, …).
        host_id: Host CAN id used in requests.
        timeout_s: Time to wait for each reply, s (at least ``$ROBOCAL_REPLY_TIMEOUT_MS``, see
            :func:`robocal.backends.reply_timeout_floor_s`).
        bus: An already open python-can bus to use instead of opening one (not closed by :meth:`close`).
        bus_options: More keyword arguments of ``can.Bus`` (``socketcand``: ``host``, ``port``).
    """

    def __init__(
        self,
        channel: str,
        motors: Sequence[MotorSpec],
        *,
        interface: str = "socketcan",
        host_id: int = DEFAULT_HOST_ID,
        timeout_s: float = DEFAULT_TIMEOUT_S,
        bus: Any = None,
        bus_options: Mapping[str, Any] | None = None,
    ) -> None:
        if not timeout_s > 0:
            raise UsageError(f"Robstride bus {channel}: timeout {timeout_s} s must be > 0")
        self.channel = channel
        self.interface = interface
        self.host_id = host_id
        self.timeout_s = max(float(timeout_s), reply_timeout_floor_s())
        self.motors: dict[str, MotorSpec] = {}
        self._by_id: dict[int, MotorSpec] = {}
        self._limits: dict[int, ModelLimits] = {}
        for m in motors:
            if not 0 < m.can_id < 0xFF:
                raise UsageError(f"motor {m.name!r}: CAN id {m.can_id} must be between 1 and 254")
            if m.name in self.motors or m.can_id in self._by_id:
                raise UsageError(f"Robstride bus {channel}: motor {m.name!r} (id {m.can_id}) is listed twice")
            self.motors[m.name] = m
            self._by_id[m.can_id] = m
            self._limits[m.can_id] = model_limits(m.model)
        self._can = require("can", "the Robstride CAN backend")
        self._owns_bus = bus is None
        self._bus = bus
        if bus is None:
            valid = sorted(getattr(self._can, "VALID_INTERFACES", ()))
            if valid and interface not in valid:
                raise UsageError(
                    f"CAN interface {interface!r} is unknown to python-can; expected one of {', '.join(valid)}"
                )
            self._bus = open_within(
                OPEN_DEADLINE_S + self.timeout_s,
                lambda: self._can.Bus(
                    channel=channel, interface=interface, receive_own_messages=False, **dict(bus_options or {})
                ),
                f"CAN {interface}:{channel}",
            )

    # ----------------------------------------------------------------------------------------- lifecycle
    def close(self) -> None:
        """Close the CAN channel (if this object opened it)."""
        if self._bus is not None and self._owns_bus:
            self._bus.shutdown()
        self._bus = None

    def _spec(self, motor: str | int) -> MotorSpec:
        if isinstance(motor, int):
            if motor not in self._by_id:
                raise UsageError(f"Robstride bus {self.channel}: no motor with CAN id {motor}")
            return self._by_id[motor]
        if motor not in self.motors:
            raise UsageError(f"Robstride bus {self.channel}: no motor named {motor!r}")
        return self.motors[motor]

    def _where(self, spec: MotorSpec) -> str:
        return f"motor {spec.name!r} (CAN id {spec.can_id} on {self.interface}:{self.channel})"

    # ---------------------------------------------------------------------------------------- transport
    def _send(self, arb: int, data: bytes) -> None:
        if self._bus is None:
            raise DeviceError(f"Robstride bus {self.channel} is closed")
        msg = self._can.Message(arbitration_id=arb, data=data, is_extended_id=True)
        try:
            self._bus.send(msg, timeout=self.timeout_s)
        except Exception as exc:
            raise DeviceError(f"CAN {self.interface}:{self.channel}: send failed ({exc})") from None

    def _receive(self, deadline: float) -> Iterator[tuple[int, int, int, Any]]:
        """Extended frames received before ``deadline``, as ``(comm_type, motor_id, low8, message)``.

        Frames already waiting when the deadline has passed are still taken (without waiting): this process may
        have been descheduled past the deadline while the replies arrived, and those came in time.
        """
        for msg in frames_until(self._bus, deadline, extended=True, now=time.monotonic):
            comm, data16, low = split_id(msg.arbitration_id)
            yield comm, data16 & 0xFF, low, msg  # every reply carries the motor id in bits 15..8

    def _collect(
        self, want: dict[int, set[int]], deadline: float, *, any_host: bool = False
    ) -> dict[int, tuple[int, bytes]]:
        """Receive until each motor in ``want`` (id → accepted types) answered or the deadline passed.

        A reply counts when bits 7..0 carry this bus's host id (the motor answers the host id of the request),
        or for any host id with ``any_host``: a type-1 (MIT) request carries the torque where the others carry
        the host id, so the motor addresses its feedback to a host it keeps (the last one that addressed it, in
        the simulator; possibly another program's); the motor id in bits 15..8 still picks the reply.
        """
        got: dict[int, tuple[int, bytes]] = {}
        for comm, motor_id, low, msg in self._receive(deadline) if want else ():
            if comm != CommType.GET_ID and low != self.host_id and not any_host:
                continue  # addressed to another host
            if motor_id in want and comm in want[motor_id] and motor_id not in got:
                got[motor_id] = (msg.arbitration_id, bytes(msg.data))
                if len(got) == len(want):
                    break
        missing = [self._by_id[i] for i in want if i not in got]
        if missing:
            names = ", ".join(self._where(m) for m in missing)
            raise CalibTimeoutError(f"no reply within {self.timeout_s:g} s from {names}")
        return got

    def _drain(self) -> None:
        """Drop replies that came too late for an earlier request, or answer frames sent without a wait."""
        for _ in range(LATE_FRAMES):
            if self._bus.recv(timeout=0.0) is None:
                return

    def _request_many(
        self, frames: Mapping[int, tuple[int, bytes]], reply_types: set[int], *, any_host: bool = False
    ) -> dict[int, tuple[int, bytes]]:
        if self._bus is not None:
            self._drain()
        for arb, data in frames.values():
            self._send(arb, data)
        want = dict.fromkeys(frames, reply_types)
        return self._collect(want, time.monotonic() + self.timeout_s, any_host=any_host)

    def _feedback_all(self, frames: Mapping[int, tuple[int, bytes]], *, mit: bool = False) -> dict[str, Feedback]:
        got = self._request_many(frames, {CommType.FEEDBACK}, any_host=mit)
        return {self._by_id[i].name: decode_feedback(a, d, self._limits[i]) for i, (a, d) in got.items()}

    def _simple(self, motor: str | int, comm: int, data: bytes = bytes(8)) -> Feedback:
        spec = self._spec(motor)
        frame = (make_id(comm, self.host_id, spec.can_id), data)
        return self._feedback_all({spec.can_id: frame})[spec.name]

    # ------------------------------------------------------------------------------------------ commands
    def ping(self, motor: str | int) -> int:
        """Type 0: ask the motor for its 64-bit MCU unique id."""
        spec = self._spec(motor)
        frame = (make_id(CommType.GET_ID, self.host_id, spec.can_id), bytes(8))
        _arb, data = self._request_many({spec.can_id: frame}, {CommType.GET_ID})[spec.can_id]
        return int.from_bytes(data, "little")

    def probe(self, can_ids: Iterable[int]) -> set[int]:
        """Send type 0 (device id, harmless) to each CAN id and return the ids that answered in time."""
        ids = sorted(set(can_ids))
        for i in ids:
            self._send(make_id(CommType.GET_ID, self.host_id, i), bytes(8))
        found: set[int] = set()
        for comm, motor_id, _low, _msg in self._receive(time.monotonic() + self.timeout_s) if ids else ():
            if comm == CommType.GET_ID and motor_id in ids:
                found.add(motor_id)
                if len(found) == len(ids):
                    break
        return found

    def enable(self, motor: str | int) -> Feedback:
        """Type 3: enable (run mode)."""
        return self._simple(motor, CommType.ENABLE)

    def stop(self, motor: str | int, clear_faults: bool = False) -> Feedback:
        """Type 4: stop (reset mode); ``clear_faults`` also clears faults."""
        return self._simple(motor, CommType.STOP, bytes([1 if clear_faults else 0, 0, 0, 0, 0, 0, 0, 0]))

    def torque_off_nowait(self, motors: Iterable[str | int] | None = None) -> None:
        """The no-torque MIT frame, then stop (type 4, reset mode), to each motor (all by default); no reply awaited.

        The first frames of a limp (``limp_all``): each motor's torque goes off as fast as the frames go out,
        whatever another motor's replies do (they are dropped before the next exchange). Always allowed. Every
        frame is tried; the first send that failed is raised afterwards.

        Raises:
            DeviceError: A frame could not be sent (a closed or lost channel).
        """
        specs = [self._spec(m) for m in (self.motors if motors is None else motors)]
        frames = [encode_mit_command(s.can_id, 0.0, 0.0, 0.0, 0.0, 0.0, self._limits[s.can_id]) for s in specs]
        frames += [(make_id(CommType.STOP, self.host_id, s.can_id), bytes(8)) for s in specs]
        failed: DeviceError | None = None
        for arb, data in frames:
            try:
                self._send(arb, data)
            except DeviceError as exc:
                failed = failed or exc
        if failed is not None:
            raise failed

    def mit_command(
        self,
        motor: str | int,
        position_rad: float,
        velocity_rad_s: float,
        kp: float,
        kd: float,
        torque_nm: float,
    ) -> Feedback:
        """Type 1: one MIT command (motor frame) and its feedback."""
        return self.mit_many({motor: (position_rad, velocity_rad_s, kp, kd, torque_nm)})[
            self._spec(motor).name
        ]

    def mit_many(
        self, commands: Mapping[str | int, tuple[float, float, float, float, float]]
    ) -> dict[str, Feedback]:
        """Type 1 to several motors, then wait for all feedback.

        Args:
            commands: Motor → ``(position_rad, velocity_rad_s, kp, kd, torque_nm)``, motor frame.

        Returns:
            Motor name → feedback.
        """
        frames: dict[int, tuple[int, bytes]] = {}
        for motor, (p, v, kp, kd, t) in commands.items():
            spec = self._spec(motor)
            frames[spec.can_id] = encode_mit_command(spec.can_id, p, v, kp, kd, t, self._limits[spec.can_id])
        return self._feedback_all(frames, mit=True)

    def zero_torque(self, motors: Iterable[str | int] | None = None) -> dict[str, Feedback]:
        """Passive read: MIT ``(0, 0, 0, 0, 0)`` to each motor (all by default); never moves a joint."""
        names = list(self.motors) if motors is None else list(motors)
        return self.mit_many(dict.fromkeys(names, (0.0, 0.0, 0.0, 0.0, 0.0)))

    def read_param(self, motor: str | int, index: int) -> float:
        """Type 17: read one parameter.

        Raises:
            ProtocolError: The motor answered with an error status or another index.
        """
        return self.read_param_many([motor], index)[self._spec(motor).name]

    def read_param_many(self, motors: Iterable[str | int], index: int) -> dict[str, float]:
        """Type 17 to several motors for the same index; motor name → value."""
        specs = [self._spec(m) for m in motors]
        frames = {s.can_id: encode_param_read(self.host_id, s.can_id, index) for s in specs}
        got = self._request_many(frames, {CommType.PARAM_READ})
        out: dict[str, float] = {}
        for s in specs:
            _motor, idx, ok, value = decode_param_reply(*got[s.can_id])
            if not ok or idx != index:
                raise ProtocolError(f"{self._where(s)}: parameter {index:#06x} read failed (status or index)")
            out[s.name] = value
        return out

    def write_param(self, motor: str | int, index: int, value: float) -> Feedback:
        """Type 18: write one parameter (lost at power-off unless :meth:`save` is called)."""
        spec = self._spec(motor)
        frame = encode_param_write(self.host_id, spec.can_id, index, value)
        return self._feedback_all({spec.can_id: frame})[spec.name]

    def arm_watchdog(self, motor: str | int, timeout_s: float) -> float:
        """Arm the motor's host-loss watchdog: ``canTimeout`` (0x7028, RAM; robocal never saves it).

        With no frame for ``timeout_s`` the motor enters reset mode (stops pushing) on its own.

        Returns:
            The ``canTimeout`` the motor had before (s; 0: off), for :meth:`disarm_watchdog`.
        """
        before = self.read_param(motor, Param.CAN_TIMEOUT) / CAN_TIMEOUT_UNITS_PER_S
        self.write_param(motor, Param.CAN_TIMEOUT, round(timeout_s * CAN_TIMEOUT_UNITS_PER_S))
        return before

    def disarm_watchdog(self, motor: str | int, timeout_s: float = 0.0) -> None:
        """Put ``canTimeout`` back (default 0: off, the factory setting)."""
        self.write_param(motor, Param.CAN_TIMEOUT, round(timeout_s * CAN_TIMEOUT_UNITS_PER_S))

    def read_position(self, motor: str | int) -> float:
        """``mechPos`` (0x7019) as float32, motor frame, rad."""
        return self.read_param(motor, Param.MECH_POS)

    def read_zero_sta(self, motor: str | int) -> int:
        """``zero_sta`` (0x7029): 0 → power-on range ``[0, 2π)``, 1 → ``[−π, π)``."""
        return int(self.read_param(motor, Param.ZERO_STA))

    def read_add_offset(self, motor: str | int) -> float:
        """``add_offset`` (0x702B), rad."""
        return self.read_param(motor, Param.ADD_OFFSET)

    def read_firmware_version(self, motor: str | int) -> str:
        """Type 4 with ``00 C4``: the firmware version as ``"a.b.c.d"``."""
        spec = self._spec(motor)
        frame = (make_id(CommType.STOP, self.host_id, spec.can_id), FIRMWARE_QUERY)
        got = self._request_many({spec.can_id: frame}, {CommType.STOP})
        return decode_firmware_reply(*got[spec.can_id])[1]

    def set_zero(self, motor: str | int, *, confirm: bool = False) -> Feedback:
        """Type 6: make the current pose read 0. Refused unless ``confirm`` is True, and in PP mode.

        Reads the firmware version and run mode first (type 6 is blocked in PP mode; old firmware jumped
        toward the previous target after zeroing).
        """
        spec = self._spec(motor)
        if not confirm:
            raise UsageError(f"{self._where(spec)}: set-zero (type 6) needs an explicit confirm=True")
        self.read_firmware_version(spec.name)
        if int(self.read_param(spec.name, Param.RUN_MODE)) == 1:
            raise UsageError(f"{self._where(spec)}: set-zero is refused in PP mode (run_mode 1)")
        return self._simple(spec.name, CommType.SET_ZERO, bytes([1, 0, 0, 0, 0, 0, 0, 0]))

    def save(self, motor: str | int, *, confirm: bool = False) -> Feedback:
        """Type 22: persist parameters written with type 18. Refused unless ``confirm`` is True."""
        spec = self._spec(motor)
        if not confirm:
            raise UsageError(f"{self._where(spec)}: save (type 22) needs an explicit confirm=True")
        return self._simple(spec.name, CommType.SAVE, SAVE_PAYLOAD)
