"""The answering thread every simulated CAN motor bus shares (Robstride, Damiao): one channel, many motors.

:class:`SimCanChannel` opens a python-can channel, answers each frame addressed to one of its motors from a thread
(the vendor's subclass routes and answers: :meth:`SimCanChannel._answer`), lets a motor's wall-clock watchdog act
when the host falls silent (:meth:`SimCanChannel._tick`), and, on python-can's in-process ``virtual`` interface,
registers :meth:`SimCanChannel.settle` with the motors' simulated clock: a marker frame sent behind the host's
frames is acknowledged when the thread gets there, so a request whose reply is lost is applied before simulated
time moves on. A transport that goes away (a closed socket) ends the thread quietly.
"""

from __future__ import annotations

import threading
from typing import Any, ClassVar

from ...core.lifecycle import StartsOnEnter
from ...errors import DeviceError
from .. import require

__all__ = ["SimCanChannel"]


class SimCanChannel(StartsOnEnter):
    """A thread answering, on one CAN channel, for the motors of one simulated bus.

    Args:
        channel: python-can channel.
        interface: python-can interface (``virtual``: in-process; others reach other processes).
        clocks: The motors' simulated clocks (settled on ``virtual``).
        bus_kwargs: More arguments for ``can.Bus``.

    Use as a context manager, or call :meth:`start` and :meth:`stop`.
    """

    VENDOR: ClassVar[str] = "CAN"
    """For messages and the thread's name."""
    MARKER_ID: ClassVar[int] = 0x7FA
    """Arbitration id of :meth:`settle`'s marker frame (one the vendor's motors and hosts never use)."""
    MARKER_EXTENDED: ClassVar[bool] = False
    """Whether the marker frame has an extended (29-bit) id."""

    def __init__(
        self,
        channel: str,
        *,
        interface: str = "virtual",
        clocks: dict[int, Any] | None = None,
        bus_kwargs: dict[str, Any] | None = None,
    ) -> None:
        self.channel = channel
        self.interface = interface
        self.lock = threading.Lock()
        """Held while a frame is handled: take it to change a motor from another thread."""
        self._bus_kwargs = dict(bus_kwargs or {})
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        self._bus: Any = None
        self._marker_bus: Any = None
        self._settles: list[threading.Event] = []
        self._clocks = {k: c for k, c in (clocks or {}).items() if c is not None}

    # ------------------------------------------------------------------------------------------ vendor
    def _after_open(self, bus: Any) -> None:
        """Adjust the freshly opened channel (nothing by default)."""

    def _tick(self) -> None:
        """Called with :attr:`lock` held before each frame (and every 20 ms): wall-clock watchdogs."""

    def _answer(self, msg: Any) -> list[Any]:
        """The python-can messages to send in answer to ``msg`` (the vendor's routing; take :attr:`lock`)."""
        raise NotImplementedError

    # ------------------------------------------------------------------------------------------ life cycle
    def start(self) -> Any:
        """Open the channel and start answering."""
        can = require("can", f"the simulated {self.VENDOR} bus")
        try:
            self._bus = can.Bus(
                channel=self.channel, interface=self.interface, receive_own_messages=False, **self._bus_kwargs
            )
        except Exception as exc:  # python-can raises CanError / OSError / ValueError by interface
            raise DeviceError(f"cannot open CAN {self.interface}:{self.channel}: {exc}") from None
        self._after_open(self._bus)
        self._stop.clear()
        name = f"sim-{self.VENDOR.lower()}-{self.channel}"
        self._thread = threading.Thread(target=self._run, name=name, daemon=True)
        self._thread.start()
        if self.interface == "virtual":
            for clock in self._clocks.values():
                clock.add_settler(self.settle)
        return self

    def settle(self, timeout_s: float = 10.0) -> None:
        """Return once every frame sent on the channel so far has been handled (for ``SimClock.sleep``)."""
        can = require("can", f"the simulated {self.VENDOR} bus")
        if self._thread is None or not self._thread.is_alive():
            return
        if self._marker_bus is None:
            self._marker_bus = can.Bus(channel=self.channel, interface="virtual", receive_own_messages=False)
        done = threading.Event()
        self._settles.append(done)
        self._marker_bus.send(
            can.Message(arbitration_id=self.MARKER_ID, data=b"settle", is_extended_id=self.MARKER_EXTENDED)
        )
        done.wait(timeout_s)

    def stop(self) -> None:
        """Stop answering and close the channel."""
        for clock in self._clocks.values():
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

    def _run(self) -> None:
        bus = self._bus
        while not self._stop.is_set():
            try:
                msg = bus.recv(timeout=0.02)
            except Exception:  # the transport went away (a closed socket): stop answering
                return
            with self.lock:  # a host that fell silent: the motors' watchdogs on the wall clock
                self._tick()
            if msg is None:
                continue
            if bool(msg.is_extended_id) == self.MARKER_EXTENDED and msg.arbitration_id == self.MARKER_ID:
                if self._settles:
                    self._settles.pop(0).set()
                continue
            for reply in self._answer(msg):
                try:
                    bus.send(reply)
                except Exception:  # the transport went away
                    return
