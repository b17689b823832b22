"""Simulated Robstride motors answering the private CAN protocol on python-can's ``virtual`` bus.

A :class:`SimMotor` is the physics and firmware state of one motor: a hidden factory zero, the true wiring
direction, hard stops, encoder noise and the power-on wrap (``[0, 2π)`` with ``zero_sta`` 0, ``[−π, π)`` with
``zero_sta`` 1). A :class:`SimMotorBus` is one CAN channel: a thread that owns a ``virtual`` bus, decodes
every request addressed to one of its motors and answers it as the firmware would (types 0, 1, 3, 4, 6, 7, 17,
18, 22).

Without a plant the joint's true position is set from outside (by a simulated operator or a test), so a
simulation runs as fast as the protocol allows, not in real time. With a :class:`~.physics.JointPlant` and a
:class:`~.physics.SimClock` the commands move the joint: every request first advances the clock by the bus
latency and integrates the plant up to it, under the firmware's MIT law as it stood (``τ = kp·(p − θ) +
kd·(v − ω) + τ_ff``, motor frame, clipped at the model's torque range and the ``limit_torque`` parameter
0x700B; zero torque in reset mode). ``canTimeout`` (0x7028, 20000 = 1 s) is the manual's host-loss watchdog: a
motor in run mode that hears no frame for that long enters reset mode (limp), on the simulated clock with a
plant, on the monotonic clock without (checked by the bus thread every 20 ms). The type-2 feedback then carries
the plant's position, velocity and torque; a latched overload sets fault bit 4 (bit 20 of the identifier; the torque is cut) until a type-4 stop with
"clear faults"; a plant that does not answer (pressed into a stop, :attr:`JointPlant.answers`) loses its reply.
"""

from __future__ import annotations

import contextlib
import math
import socket
import struct
import time
from collections.abc import Iterable
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ...errors import DeviceError
from .. import require
from ..sim.can_channel import SimCanChannel
from ..sim.physics import Drive, JointPlant, SimClock
from .protocol import (
    FIRMWARE_QUERY,
    CommType,
    Feedback,
    ModelLimits,
    Param,
    decode_mit_command,
    encode_feedback,
    encode_firmware_reply,
    encode_param_reply,
    make_id,
    model_limits,
    split_id,
    unpack_param_value,
)

__all__ = ["SimMotor", "SimMotorBus"]

FOUR_PI = 2.0 * math.tau


@dataclass
class SimMotor:
    """State of one simulated motor (mutable: it is the simulated hardware).

    Attributes:
        can_id: Motor CAN id.
        model: Model name (``"rs-00"`` …).
        direction: True wiring sign: ``raw = direction·q + factory_zero`` (continuous, before wrapping).
        factory_zero_rad: Hidden factory zero: raw reading at joint position 0 on the continuous branch.
        stop_lower_rad: Lower hard stop, joint frame, rad.
        stop_upper_rad: Upper hard stop, joint frame, rad.
        noise_rad: Standard deviation of the encoder noise, rad.
        zero_sta: 0 → power-on reading in ``[0, 2π)``; 1 → ``[−π, π)``.
        single_turn: Report positions wrapped into the power-on range on every reading (a single-turn encoder
            or a publisher that wraps) instead of counting turns within ±4π.
        q_rad: True joint position, rad (set by the operator; clamped to the stops).
        v_rad_s: True joint velocity, rad/s.
        firmware: Firmware version reported by the ``00 C4`` query.
        seed: Seed of the noise generator.
    """

    can_id: int
    model: str = "rs-00"
    direction: int = 1
    factory_zero_rad: float = 0.0
    stop_lower_rad: float = -math.pi
    stop_upper_rad: float = math.pi
    noise_rad: float = 0.0
    zero_sta: int = 0
    single_turn: bool = False
    q_rad: float = 0.0
    v_rad_s: float = 0.0
    firmware: tuple[int, int, int, int] = (0, 0, 3, 6)
    seed: int = 0
    host_id: int = 0xFD
    """The last host id that addressed the motor (any request but type 1); replies to type 1 go there."""
    master_id: int | None = None
    """A fixed host id for the replies to type 1 instead of :attr:`host_id` (firmware that keeps a master id)."""
    mode: int = 0
    run_mode: int = 0
    add_offset_rad: float = 0.0
    zero_shift_rad: float = 0.0
    last_command: tuple[float, float, float, float, float] | None = None
    requests: dict[int, int] = field(default_factory=dict)
    plant: JointPlant | None = None
    """Physics of the joint (joint frame); None: the position is set from outside."""
    clock: SimClock | None = None
    """Simulated time the plant is integrated to at each request (required with a plant)."""
    latency_s: float = 0.0005
    """Bus latency added to the simulated clock per request (with a plant)."""
    limit_torque_nm: float | None = None
    """``limit_torque`` (0x700B); None: the model's torque range."""
    can_timeout: int = 0
    """``canTimeout`` (0x7028, 20000 = 1 s, 0 off): in run mode, no frame for that long puts the motor in reset mode."""
    last_rx_s: float | None = None
    """When the last frame addressed to the motor came (its clock: simulated with a plant, else monotonic)."""
    watchdog_trips: list[tuple[float, float]] = field(default_factory=list)
    """(last frame, trip time) of every CAN timeout that put the motor into reset mode."""
    _branch_rad: float = 0.0
    _rng: Any = None

    def __post_init__(self) -> None:
        self.limits: ModelLimits = model_limits(self.model)
        self._rng = np.random.default_rng(self.seed)
        if self.plant is not None and self.clock is None:
            raise DeviceError(f"simulated motor {self.can_id}: a plant needs a simulated clock")
        if self.plant is not None:
            self.q_rad = self.plant.q_rad
        self.set_position(self.q_rad)
        self.power_on()

    # ------------------------------------------------------------------------------------------ physics
    def set_position(self, q_rad: float, v_rad_s: float = 0.0) -> None:
        """Move the joint (clamped to the hard stops)."""
        self.q_rad = min(max(q_rad, self.stop_lower_rad), self.stop_upper_rad)
        self.v_rad_s = v_rad_s
        if self.plant is not None:
            self.plant.set_state(self.q_rad, v_rad_s)

    def drive(self) -> Drive:
        """The firmware's torque law now, in the joint frame (limp unless enabled with an MIT command)."""
        if self.mode != 2 or self.last_command is None:
            return Drive()
        p, v, kp, kd, t = self.last_command
        d = self.direction
        limit = self.limits.t_max_nm
        if self.limit_torque_nm is not None:
            limit = min(limit, max(0.0, self.limit_torque_nm))
        q_ref = d * (p - self.true_homing_offset_rad)
        return Drive(kp, kd, q_ref, d * v, d * t, limit)

    def now_s(self) -> float:
        """The motor's time: the simulated clock with a plant, else the monotonic clock."""
        return self.clock.now() if self.clock is not None else time.monotonic()

    def check_watchdog(self, now_s: float | None = None) -> bool:
        """Apply ``canTimeout``: in run mode with no frame for that long, the motor enters reset mode (limp).

        With a plant the joint is integrated under the last command up to the trip, then limp. Returns whether it
        tripped now.
        """
        if self.can_timeout <= 0 or self.mode != 2 or self.last_rx_s is None:
            return False
        due = self.last_rx_s + self.can_timeout / 20000.0
        if (self.now_s() if now_s is None else now_s) < due:
            return False
        if self.plant is not None:
            self.plant.run_until(due, self.drive())
        self.mode = 0
        self.watchdog_trips.append((self.last_rx_s, due))
        return True

    def sync(self) -> None:
        """Integrate the plant up to the clock under the current command (no-op without a plant)."""
        if self.plant is None or self.clock is None:
            return
        self.check_watchdog()
        self.plant.run_until(self.clock.now(), self.drive())
        self.q_rad, self.v_rad_s = self.plant.q_rad, self.plant.v_rad_s

    def _continuous_raw(self) -> float:
        return self.direction * self.q_rad + self.factory_zero_rad - self.zero_shift_rad + self.add_offset_rad

    def _wrap_power_on(self, x: float) -> float:
        lo = -math.pi if self.zero_sta == 1 else 0.0
        return (x - lo) % math.tau + lo

    def power_on(self) -> None:
        """Power-cycle: the reading restarts inside one turn (by ``zero_sta``); run-time state is reset."""
        raw = self._continuous_raw()
        self._branch_rad = self._wrap_power_on(raw) - raw
        self.mode = 0
        self.last_command = None

    @property
    def true_homing_offset_rad(self) -> float:
        """The offset that maps this power-on's readings to the joint: ``q = direction·(raw − offset)``."""
        return self.factory_zero_rad - self.zero_shift_rad + self.add_offset_rad + self._branch_rad

    def reading_rad(self, noisy: bool = True) -> float:
        """Position the motor reports now (motor frame, rad)."""
        if self.plant is not None and noisy:  # the plant's encoder: quantised, its own noise
            x = self.direction * self.plant.read().q_rad + self.true_homing_offset_rad
        else:
            x = self._continuous_raw() + self._branch_rad
        if noisy and self.noise_rad > 0:
            x += float(self._rng.normal(0.0, self.noise_rad))
        if self.single_turn:
            return self._wrap_power_on(x)
        return (x + FOUR_PI) % (2 * FOUR_PI) - FOUR_PI

    def feedback(self, host_id: int) -> Feedback:
        """The type-2 frame content for the current state."""
        tau = 0.0
        faults = 0
        if self.plant is not None:
            tau = self.direction * self.plant.tau_motor_nm if self.mode == 2 else 0.0
            faults = 0x10 if self.plant.latched else 0
        elif self.last_command is not None and self.mode == 2:
            p, v, kp, kd, t_ff = self.last_command
            raw = self.reading_rad(noisy=False)
            tau = kp * (p - raw) + kd * (v - self.direction * self.v_rad_s) + t_ff
            tau = max(-self.limits.t_max_nm, min(self.limits.t_max_nm, tau))
        return Feedback(
            motor_id=self.can_id,
            host_id=host_id,
            mode=self.mode,
            faults=faults,
            position_rad=self.reading_rad(),
            velocity_rad_s=self.direction * self.v_rad_s,
            torque_nm=tau,
            temperature_c=30.0,
        )

    # ----------------------------------------------------------------------------------------- protocol
    def handle(self, arbitration_id: int, data: bytes) -> list[tuple[int, bytes]]:
        """Answer one request frame addressed to this motor; returns the reply frames."""
        comm, _, _ = split_id(arbitration_id)
        self.requests[comm] = self.requests.get(comm, 0) + 1
        if self.plant is not None and self.clock is not None:
            self.clock.advance(self.latency_s)
            self.sync()
        else:
            self.check_watchdog()
        self.last_rx_s = self.now_s()
        replies = self._handle(arbitration_id, data)
        if self.plant is not None and not self.plant.answers():
            return []  # the reply is lost (the command was heard and obeyed)
        return replies

    def _handle(self, arbitration_id: int, data: bytes) -> list[tuple[int, bytes]]:
        comm, data16, _ = split_id(arbitration_id)
        host = data16 & 0xFF
        if comm != CommType.MIT:
            self.host_id = host
        if comm == CommType.SET_ID and 0 < (data16 >> 8) < 0xFF:
            self.can_id = data16 >> 8  # new id in bits 23..16; answered with a type-0 frame from the new id
        if comm in (CommType.GET_ID, CommType.SET_ID):
            uid = struct.pack("<Q", 0x5253000000000000 | self.can_id)
            return [(make_id(CommType.GET_ID, self.can_id, 0xFE), uid)]
        if comm == CommType.MIT:
            _, p, v, kp, kd, t = decode_mit_command(arbitration_id, data, self.limits)
            # type 1 carries the torque where the others carry the host id: answer the last host seen
            host = self.host_id if self.master_id is None else self.master_id
            self.last_command = (p, v, kp, kd, t)
        elif comm == CommType.ENABLE:
            self.mode = 2
        elif comm == CommType.STOP:
            if bytes(data[:2]) == FIRMWARE_QUERY[:2]:
                return [encode_firmware_reply(self.can_id, host, self.firmware)]
            self.mode = 0
            if data[:1] == b"\x01" and self.plant is not None:
                self.plant.clear_overload()
        elif comm == CommType.SET_ZERO:
            if self.run_mode == 1:  # blocked in PP mode
                return [encode_feedback(self.feedback(host), self.limits)]
            self.zero_shift_rad += self._continuous_raw() + self._branch_rad
        elif comm == CommType.PARAM_READ:
            index = struct.unpack("<H", data[:2])[0]
            value = self._read_param(index)
            if value is None:
                return [encode_param_reply(self.can_id, host, index, 0.0, ok=False)]
            return [encode_param_reply(self.can_id, host, index, value)]
        elif comm == CommType.PARAM_WRITE:
            index = struct.unpack("<H", data[:2])[0]
            value = unpack_param_value(index, bytes(data[4:8]))
            if index == Param.ZERO_STA:
                self.zero_sta = int(value)
            elif index == Param.ADD_OFFSET:
                self.add_offset_rad = value  # takes effect on the reading at the next power-on
                self._branch_rad -= value
            elif index == Param.RUN_MODE:
                self.run_mode = int(value)
            elif index == Param.LIMIT_TORQUE:
                self.limit_torque_nm = value
            elif index == Param.CAN_TIMEOUT:
                self.can_timeout = int(value)
        elif comm == CommType.SAVE:
            pass
        else:
            return []
        return [encode_feedback(self.feedback(host), self.limits)]

    def _read_param(self, index: int) -> float | None:
        if index == Param.MECH_POS:
            return self.reading_rad()
        if index == Param.MECH_VEL:
            return self.direction * self.v_rad_s
        if index == Param.ZERO_STA:
            return float(self.zero_sta)
        if index == Param.ADD_OFFSET:
            return self.add_offset_rad
        if index == Param.RUN_MODE:
            return float(self.run_mode)
        if index == Param.LIMIT_TORQUE:
            return self.limits.t_max_nm if self.limit_torque_nm is None else self.limit_torque_nm
        if index == Param.VBUS:
            return 24.0
        if index == Param.CAN_TIMEOUT:
            return float(self.can_timeout)
        if index == 0x701E:  # loc_kp (the manual's example)
            return 30.0
        return None


_SETTLE_ID = 0x7FA
"""Standard (11-bit) id of the marker frame of :meth:`SimMotorBus.settle` (the Robstride protocol is 29-bit)."""
_IP_MULTICAST_ALL = 49  # Linux: deliver only the groups this socket joined (default: every group on the host)
_IPV6_MULTICAST_ALL = 29


def _only_own_group(bus: Any) -> None:
    """Keep a udp_multicast channel from hearing the other channels' groups (they share one UDP port).

    Linux delivers a datagram for any multicast group joined on the host to every socket bound to its port;
    without this, the simulated ``can1`` motors would answer requests sent on ``can0``.
    """
    sock = getattr(getattr(bus, "_multicast", None), "_socket", None)
    if sock is None:
        return
    with contextlib.suppress(OSError):
        if sock.family == socket.AF_INET:
            sock.setsockopt(socket.IPPROTO_IP, _IP_MULTICAST_ALL, 0)
        else:
            sock.setsockopt(socket.IPPROTO_IPV6, _IPV6_MULTICAST_ALL, 0)


class SimMotorBus(SimCanChannel):
    """A thread answering, on one ``virtual`` CAN channel, for every motor in ``motors``.

    The channel, its thread and the settling on a simulated clock are :class:`~..sim.can_channel.SimCanChannel`'s;
    this routes a request by the motor id in bits 7..0 of its 29-bit id. The marker frame of :meth:`settle` has a
    standard (11-bit) id: the Robstride protocol is 29-bit.

    Args:
        channel: python-can channel (``virtual``: a name unique per simulated robot; ``socketcan``: ``vcan0``;
            ``udp_multicast``: a multicast group address).
        motors: The simulated motors on this channel.
        silent: CAN ids that never answer (to test timeouts).
        interface: python-can interface: ``virtual`` (in-process, default), or one shared with other
            processes (``socketcan`` on a vcan interface, ``udp_multicast``).

    Use as a context manager, or call :meth:`start` and :meth:`stop`.
    """

    VENDOR = "Robstride"
    MARKER_ID = _SETTLE_ID
    MARKER_EXTENDED = False

    def __init__(
        self,
        channel: str,
        motors: Iterable[SimMotor],
        silent: Iterable[int] = (),
        *,
        interface: str = "virtual",
    ) -> None:
        self.motors: dict[int, SimMotor] = {m.can_id: m for m in motors}
        self.silent = set(silent)
        super().__init__(
            channel, interface=interface, clocks={id(m.clock): m.clock for m in self.motors.values()}
        )

    def start(self) -> SimMotorBus:
        """Open the channel and start answering."""
        super().start()
        return self

    def _after_open(self, bus: Any) -> None:
        if self.interface == "udp_multicast":
            _only_own_group(bus)

    def _tick(self) -> None:
        for m in self.motors.values():
            if m.clock is None:
                m.check_watchdog()

    def _answer(self, msg: Any) -> list[Any]:
        if not msg.is_extended_id:
            return []
        can = require("can", "the simulated Robstride bus")
        motor_id = msg.arbitration_id & 0xFF
        motor = self.motors.get(motor_id)
        if motor is None or motor_id in self.silent:
            return []
        with self.lock:
            try:
                replies = motor.handle(msg.arbitration_id, bytes(msg.data))
            except Exception:  # a malformed request: a real motor ignores it
                return []
            if motor.can_id != motor_id:  # type 7 gave it a new CAN id
                self.motors[motor.can_id] = self.motors.pop(motor_id)
        return [can.Message(arbitration_id=arb, data=data, is_extended_id=True) for arb, data in replies]
