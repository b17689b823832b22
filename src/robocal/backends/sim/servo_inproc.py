"""The in-process port of a simulated servo bus: the pyserial object under the vendor SDK, without a pty.

:class:`InProcessSerial` is what :class:`~robocal.backends.sim.servo.SimServoBus` (``transport="inproc"``)
opens for the SDK's ``PortHandler`` (through :mod:`robocal.backends.inproc_serial`): :meth:`~InProcessSerial.write`
hands the packet bytes to the bus's parser (the code the pty's thread runs), which answers every whole packet at
once into :meth:`~InProcessSerial.read`'s buffer. Nothing waits and nothing polls the wall clock: a read that
finds no byte moves the port's own time (:meth:`~InProcessSerial.now_ms`, the SDK's timeout clock) on by
``idle_step_ms``, so a servo that does not answer times out after ``packet_timeout / idle_step_ms`` empty reads.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from .servo import SimServoBus

__all__ = ["IDLE_STEP_MS", "InProcessSerial"]

IDLE_STEP_MS = 1.0
"""How far an empty read moves the port's time on (ms): a 100 ms reply timeout is 100 empty reads."""


class InProcessSerial:
    """A pyserial-like port whose far end is a :class:`SimServoBus` in this process.

    Args:
        bus: The simulated bus that answers (``transport="inproc"``).
        baudrate: The speed the client opened the port at (servos hear only packets at their own baud rate).
        idle_step_ms: Port time per empty read (the SDK's timeout clock).
    """

    def __init__(self, bus: SimServoBus, baudrate: int, *, idle_step_ms: float = IDLE_STEP_MS) -> None:
        self._bus = bus
        self.baudrate = int(baudrate)
        self.is_open = True
        self.idle_step_ms = idle_step_ms
        self._rx = bytearray()
        self._time_ms = 0.0
        self.empty_reads = 0
        """Reads that found no byte (each one idle step of the port's time)."""

    @property
    def port(self) -> str:
        """The in-process port's name."""
        return self._bus.port

    @property
    def in_waiting(self) -> int:
        """Bytes of status packets not read yet."""
        return len(self._rx)

    def _check_open(self) -> None:
        if not self.is_open:  # as pyserial's PortNotOpenError (an OSError)
            raise OSError(f"{self._bus.port}: the in-process port is closed")

    def write(self, data: bytes) -> int:
        """Hand the bytes to the simulated bus; its replies are ready to read when this returns."""
        self._check_open()
        chunk = bytes(data)
        self._bus.receive(chunk)
        return len(chunk)

    def read(self, size: int = 1) -> bytes:
        """Up to ``size`` reply bytes; none waiting: ``b""`` and the port's time moves on one idle step."""
        self._check_open()
        if not self._rx:
            self.empty_reads += 1
            self._time_ms += self.idle_step_ms
            return b""
        out = bytes(self._rx[:size])
        del self._rx[:size]
        return out

    def deliver(self, data: bytes) -> None:
        """The bus's side: a status packet on the wire (dropped while the port is closed)."""
        if self.is_open:
            self._rx.extend(data)

    def flush(self) -> None:
        """Written bytes are delivered at once: nothing to wait for."""

    def reset_input_buffer(self) -> None:
        """Drop status packets not read yet."""
        self._rx.clear()

    def reset_output_buffer(self) -> None:
        """Nothing is ever pending on the way out."""

    def close(self) -> None:
        """Close the port: later reads and writes raise ``OSError`` (as pyserial's), a DeviceError from the bus."""
        self.is_open = False
        self._rx.clear()

    def now_ms(self) -> float:
        """The port's time, ms: advanced only by empty reads (the SDK's reply-timeout clock)."""
        return self._time_ms
