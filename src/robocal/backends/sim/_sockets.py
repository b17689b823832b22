"""The accept loop of the simulators' servers (the control socket, the UR primary interface)."""

from __future__ import annotations

import socket
import threading
from collections.abc import Callable

__all__ = ["accept_loop"]


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
