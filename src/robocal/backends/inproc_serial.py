"""In-process serial ports: a serial-port name that a simulator in this process answers, byte for byte.

The vendor SDKs (``scservo_sdk``, ``dynamixel_sdk``) open their port with ``serial.Serial(port_name)`` and then
only call ``write``, ``read``, ``flush``, ``reset_input_buffer``, ``in_waiting`` and ``close`` on it. A simulator
that registers a name here (``inproc://…``) is handed the SDK's bytes by its ``write`` and returns its replies
from ``read``, in the calling thread: no pseudo-terminal, no thread, no polling.
:class:`~robocal.backends._servo_common.SdkBusBase` (the Feetech and Dynamixel buses) looks its port up here
first; the SDK itself is unmodified and builds and checks the same packets as on a real port.

An in-process port keeps its own time (:meth:`InProcessPort.now_ms`), on which the SDK's reply timeout runs:
a read that finds no byte waiting moves it on by one idle step, so a device that does not answer times out after
``packet_timeout / idle_step`` empty reads instead of busy-polling the wall clock.
"""

from __future__ import annotations

import itertools
import threading
from collections.abc import Callable
from typing import Protocol

__all__ = ["PREFIX", "InProcessPort", "lookup", "new_name", "register", "unregister"]

PREFIX = "inproc://"
"""Every in-process port name starts with this."""


class InProcessPort(Protocol):
    """What the SDK's PortHandler uses of a pyserial ``Serial`` object, plus the port's own time."""

    baudrate: int
    is_open: bool

    @property
    def in_waiting(self) -> int:
        """Bytes ready to read."""
        ...

    def write(self, data: bytes) -> int:
        """Hand bytes to the device; returns how many were taken."""
        ...

    def read(self, size: int = 1) -> bytes:
        """Up to ``size`` bytes of the device's replies (no wait: ``b""`` when none are waiting)."""
        ...

    def flush(self) -> None:
        """Wait until written bytes are sent (they are, at once)."""
        ...

    def reset_input_buffer(self) -> None:
        """Drop replies not read yet."""
        ...

    def close(self) -> None:
        """Close the port."""
        ...

    def now_ms(self) -> float:
        """The port's time in milliseconds (the SDK's reply timeouts run on it)."""
        ...


Opener = Callable[[int], InProcessPort]
"""Opens the port at a baud rate (bit/s); called by the SDK each time it (re)opens it."""

_PORTS: dict[str, Opener] = {}
_LOCK = threading.Lock()
_COUNTER = itertools.count(1)


def new_name(what: str) -> str:
    """A fresh port name ``inproc://<what>-<n>``, unique in this process."""
    return f"{PREFIX}{what}-{next(_COUNTER)}"


def register(name: str, opener: Opener) -> None:
    """Make ``name`` an in-process port opened by ``opener`` (a name already in use is replaced)."""
    with _LOCK:
        _PORTS[name] = opener


def unregister(name: str) -> None:
    """Forget ``name`` (no error if it is not registered)."""
    with _LOCK:
        _PORTS.pop(name, None)


def lookup(name: str) -> Opener | None:
    """The opener of an in-process port, or None when ``name`` is not one (a real port)."""
    if not name.startswith(PREFIX):
        return None
    with _LOCK:
        return _PORTS.get(name)
