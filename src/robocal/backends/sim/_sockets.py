"""The accept loop of the simulators' servers (the control socket, the UR ports) and a threaded TCP server."""

from __future__ import annotations

import contextlib
import socket
import threading
from collections.abc import Callable
from typing import TypeVar

__all__ = ["LoopbackServer", "accept_loop"]


def accept_loop(
    listener: socket.socket, stop: threading.Event, accepted: Callable[[socket.socket], None]
) -> None:
    """Accept connections until ``stop`` is set or ``listener`` is closed; hand each to ``accepted``.

    A listener with a timeout wakes up every timeout to look at ``stop``; any other ``OSError`` (the listener
    was shut down or closed) ends the loop.

    Args:
        listener: A bound, listening socket.
        stop: Ends the loop once set.
        accepted: Takes each new connection (in this thread: start a thread there for a long conversation).
    """
    while not stop.is_set():
        try:
            conn, _ = listener.accept()
        except TimeoutError:
            continue
        except OSError:
            return
        accepted(conn)


_Server = TypeVar("_Server", bound="LoopbackServer")


class LoopbackServer:
    """A TCP server that serves each connection in its own thread (subclasses write :meth:`_serve`).

    ``start()`` accepts in a background thread; ``stop()`` shuts every connection down and joins the threads.

    Args:
        host: Bind address.
        port: Bind port (0 = a free port; see :attr:`address`).
        name: Thread name of the connections.

    Raises:
        OSError: The address cannot be bound.
    """

    def __init__(self, *, host: str = "127.0.0.1", port: int = 0, name: str = "sim-server") -> None:
        self.name = name
        self._stop = threading.Event()
        self._listener = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
        self._listener.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        try:
            self._listener.bind((host, port))
            self._listener.listen(32)
        except OSError:
            self._listener.close()
            raise
        self._listener.settimeout(0.05)
        self._lock = threading.Lock()
        self._clients: dict[socket.socket, threading.Thread] = {}
        self._accepter: threading.Thread | None = None

    @property
    def address(self) -> tuple[str, int]:
        """``(host, port)`` the server listens on."""
        host, port = self._listener.getsockname()[:2]
        return str(host), int(port)

    @property
    def stopping(self) -> bool:
        """True once :meth:`stop` was called."""
        return self._stop.is_set()

    def start(self: _Server) -> _Server:
        """Accept connections in a background thread; returns the server."""
        self._accepter = threading.Thread(
            target=accept_loop, args=(self._listener, self._stop, self._accepted), daemon=True
        )
        self._accepter.start()
        return self

    def stop(self, timeout_s: float = 2.0) -> None:
        """Stop accepting, shut every connection down, join the threads (with a timeout)."""
        self._stop.set()
        with self._lock:
            clients = dict(self._clients)
        for conn in clients:
            with contextlib.suppress(OSError):
                conn.shutdown(socket.SHUT_RDWR)
        for t in [*clients.values(), *([self._accepter] if self._accepter else [])]:
            t.join(timeout_s)
        with contextlib.suppress(OSError):
            self._listener.close()

    def wait(self, seconds: float) -> bool:
        """Wait up to ``seconds``; True once stopped."""
        return self._stop.wait(seconds)

    def _accepted(self, conn: socket.socket) -> None:
        t = threading.Thread(target=self._serve_and_close, args=(conn,), name=self.name, daemon=True)
        with self._lock:
            self._clients[conn] = t
        t.start()

    def _serve_and_close(self, conn: socket.socket) -> None:
        try:
            self._serve(conn)
        except OSError:
            pass
        finally:
            with contextlib.suppress(OSError):
                conn.close()
            with self._lock:
                self._clients.pop(conn, None)

    def _serve(self, conn: socket.socket) -> None:
        """Talk to one client (OSError ends the conversation quietly)."""
        raise NotImplementedError
