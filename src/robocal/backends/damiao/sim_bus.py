"""Simulated Damiao motors on a CAN channel: a thread answering every frame addressed to one of them.

Frames to 0x7FF are routed by their bytes 0-1 (the ESC_ID they name), every other frame by its arbitration id
(the ESC_ID it is sent to). A reply has the frame type of the request (FD when asked in FD, as the motors on an
OpenArm's FD bus are assumed to do). The channel is python-can's ``virtual`` (in-process) by default, or any
other python-can interface another process can reach (``socketcand`` towards ``robocal sim``'s loopback server).
"""

from __future__ import annotations

import threading
from collections.abc import Iterable
from typing import Any

from ...core.lifecycle import StartsOnEnter
from ...errors import DeviceError
from .. import require
from .sim import SimDamiaoMotor
from .tables import CONFIG_ID

__all__ = ["SETTLE_ID", "SimDamiaoBus"]

SETTLE_ID = 0x1FFFFFFF
"""Extended id of the marker frame :meth:`SimDamiaoBus.settle` sends (Damiao uses only 11-bit ids, so neither a
motor nor the host takes it for one of theirs)."""


class SimDamiaoBus(StartsOnEnter):
    """A thread answering, on one CAN channel, for every motor in ``motors``.

    Args:
        channel: python-can channel (``virtual``: a name unique per simulated arm).
        motors: The simulated motors on the channel (ESC_IDs must differ).
        silent: ESC_IDs that never answer (a motor without power: to test timeouts).
        interface: python-can interface (``virtual`` by default).
        bus_kwargs: More arguments for ``can.Bus`` (e.g. ``host``/``port`` for ``socketcand``).

    Use as a context manager, or call :meth:`start` and :meth:`stop`.
    """

    def __init__(
        self,
        channel: str,
        motors: Iterable[SimDamiaoMotor],
        silent: Iterable[int] = (),
        *,
        interface: str = "virtual",
        bus_kwargs: dict[str, Any] | None = None,
    ) -> None:
        self.channel = channel
        self.interface = interface
        self.motors: list[SimDamiaoMotor] = list(motors)
        ids = [m.esc_id for m in self.motors]
        if len(set(ids)) != len(ids):
            raise DeviceError(f"simulated Damiao bus {channel}: two motors share an ESC_ID ({ids})")
        self.silent = set(silent)
        self.lock = threading.Lock()
        """Held while a frame is handled: take it to change a motor from another thread."""
        self.frames_in = 0
        self._bus_kwargs = dict(bus_kwargs or {})
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        self._bus: Any = None
        self._marker_bus: Any = None
        self._settles: list[threading.Event] = []
        self._clocks = {id(m.clock): m.clock for m in self.motors if m.clock is not None}

    def motor(self, esc_id: int) -> SimDamiaoMotor:
        """The motor listening on ``esc_id`` now.

        Raises:
            KeyError: None does.
        """
        for m in self.motors:
            if m.esc_id == esc_id:
                return m
        raise KeyError(esc_id)

    def start(self) -> SimDamiaoBus:
        """Open the channel and start answering."""
        can = require("can", "the simulated Damiao bus")
        try:
            self._bus = can.Bus(
                channel=self.channel, interface=self.interface, receive_own_messages=False, **self._bus_kwargs
            )
        except Exception as exc:  # python-can raises CanError / OSError / ValueError by interface
            raise DeviceError(f"cannot open CAN {self.interface}:{self.channel}: {exc}") from None
        self._stop.clear()
        self._thread = threading.Thread(target=self._run, name=f"sim-damiao-{self.channel}", daemon=True)
        self._thread.start()
        if self.interface == "virtual":
            for clock in self._clocks.values():
                if clock is not None:
                    clock.add_settler(self.settle)
        return self

    def settle(self, timeout_s: float = 10.0) -> None:
        """Return once every frame sent on the channel so far has been handled (for ``SimClock.sleep``)."""
        can = require("can", "the simulated Damiao bus")
        if self._thread is None or not self._thread.is_alive():
            return
        if self._marker_bus is None:
            self._marker_bus = can.Bus(channel=self.channel, interface="virtual", receive_own_messages=False)
        done = threading.Event()
        self._settles.append(done)
        self._marker_bus.send(can.Message(arbitration_id=SETTLE_ID, data=b"settle", is_extended_id=True))
        done.wait(timeout_s)

    def stop(self) -> None:
        """Stop answering and close the channel."""
        for clock in self._clocks.values():
            if clock is not None:
                clock.remove_settler(self.settle)
        if self._marker_bus is not None:
            self._marker_bus.shutdown()
            self._marker_bus = None
        self._stop.set()
        if self._thread is not None:
            self._thread.join(timeout=2.0)
            self._thread = None
        if self._bus is not None:
            self._bus.shutdown()
            self._bus = None

    def _target(self, arbitration_id: int, data: bytes) -> SimDamiaoMotor | None:
        esc = arbitration_id
        if arbitration_id == CONFIG_ID:
            if len(data) < 2:
                return None
            esc = data[0] | (data[1] << 8)
        for m in self.motors:
            if m.esc_id == esc and esc not in self.silent:
                return m
        return None

    def _run(self) -> None:
        can = require("can", "the simulated Damiao bus")
        bus = self._bus
        while not self._stop.is_set():
            try:
                msg = bus.recv(timeout=0.02)
            except Exception:  # the transport went away (a closed socket): stop answering
                return
            with self.lock:  # a silent host: TIMEOUT on the wall clock for motors without a plant
                for m in self.motors:
                    if m.clock is None:
                        m.check_timeout()
            if msg is None:
                continue
            if msg.is_extended_id:
                if msg.arbitration_id == SETTLE_ID and self._settles:
                    self._settles.pop(0).set()
                continue
            data = bytes(msg.data)
            with self.lock:
                self.frames_in += 1
                motor = self._target(msg.arbitration_id, data)
                if motor is None:
                    continue
                try:
                    replies = motor.handle(msg.arbitration_id, data)
                except Exception:  # a malformed frame: a real motor ignores it
                    continue
            for arb, payload in replies:
                reply = can.Message(
                    arbitration_id=arb, data=payload, is_extended_id=False, is_fd=bool(msg.is_fd)
                )
                try:
                    bus.send(reply)
                except Exception:  # the transport went away
                    return
