"""Simulated Damiao motors on a CAN channel: a thread answering every frame addressed to one of them.

Frames to 0x7FF are routed by their bytes 0-1 (the ESC_ID they name), every other frame by its arbitration id
(the ESC_ID it is sent to). A reply has the frame type of the request (FD when asked in FD, as the motors on an
OpenArm's FD bus are assumed to do). The channel is python-can's ``virtual`` (in-process) by default, or any
other python-can interface another process can reach (``socketcand`` towards ``robocal sim``'s loopback server).
"""

from __future__ import annotations

from collections.abc import Iterable
from typing import Any

from ...errors import DeviceError
from .. import require
from ..sim.can_channel import SimCanChannel
from .sim import SimDamiaoMotor
from .tables import CONFIG_ID

__all__ = ["SETTLE_ID", "SimDamiaoBus"]

SETTLE_ID = 0x1FFFFFFF
"""Extended id of the marker frame :meth:`SimDamiaoBus.settle` sends (Damiao uses only 11-bit ids, so neither a
motor nor the host takes it for one of theirs)."""


class SimDamiaoBus(SimCanChannel):
    """A thread answering, on one CAN channel, for every motor in ``motors``.

    The channel, its thread and the settling on a simulated clock are :class:`~..sim.can_channel.SimCanChannel`'s;
    this routes each frame to the motor it names (see the module docstring) and answers in the request's frame type.

    Args:
        channel: python-can channel (``virtual``: a name unique per simulated arm).
        motors: The simulated motors on the channel (ESC_IDs must differ).
        silent: ESC_IDs that never answer (a motor without power: to test timeouts).
        interface: python-can interface (``virtual`` by default).
        bus_kwargs: More arguments for ``can.Bus`` (e.g. ``host``/``port`` for ``socketcand``).

    Use as a context manager, or call :meth:`start` and :meth:`stop`.
    """

    VENDOR = "Damiao"
    MARKER_ID = SETTLE_ID
    MARKER_EXTENDED = True

    def __init__(
        self,
        channel: str,
        motors: Iterable[SimDamiaoMotor],
        silent: Iterable[int] = (),
        *,
        interface: str = "virtual",
        bus_kwargs: dict[str, Any] | None = None,
    ) -> None:
        self.motors: list[SimDamiaoMotor] = list(motors)
        ids = [m.esc_id for m in self.motors]
        if len(set(ids)) != len(ids):
            raise DeviceError(f"simulated Damiao bus {channel}: two motors share an ESC_ID ({ids})")
        self.silent = set(silent)
        self.frames_in = 0
        super().__init__(
            channel,
            interface=interface,
            clocks={id(m.clock): m.clock for m in self.motors},
            bus_kwargs=bus_kwargs,
        )

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
        super().start()
        return self

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

    def _tick(self) -> None:  # a silent host: TIMEOUT on the wall clock for motors without a plant
        for m in self.motors:
            if m.clock is None:
                m.check_timeout()

    def _answer(self, msg: Any) -> list[Any]:
        if msg.is_extended_id:
            return []
        can = require("can", "the simulated Damiao bus")
        data = bytes(msg.data)
        with self.lock:
            self.frames_in += 1
            motor = self._target(msg.arbitration_id, data)
            if motor is None:
                return []
            try:
                replies = motor.handle(msg.arbitration_id, data)
            except Exception:  # a malformed frame: a real motor ignores it
                return []
        fd = bool(msg.is_fd)
        return [can.Message(arbitration_id=arb, data=payload, is_extended_id=False, is_fd=fd) for arb, payload in replies]
