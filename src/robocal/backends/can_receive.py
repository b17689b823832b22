"""The reply wait every python-can bus of robocal shares (Robstride, Damiao): frames until a deadline, late ones too.

A reply that arrived before the deadline while this process was descheduled is still a reply in time: once the
deadline has passed, the frames already queued are taken without waiting (at most :data:`LATE_FRAMES`), then the
wait ends.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Iterator
from typing import Any

__all__ = ["LATE_FRAMES", "frames_until"]

LATE_FRAMES = 1024
"""At most this many frames already queued are taken once a deadline has passed."""


def frames_until(
    bus: Any, deadline: float, *, extended: bool, now: Callable[[], float] = time.monotonic
) -> Iterator[Any]:
    """The python-can messages ``bus`` receives before ``deadline`` (``time.monotonic``), late ones too.

    Those already queued when the deadline passed are taken without waiting; only extended-id frames
    (``extended``) or only standard-id ones are yielded. ``now``: the clock ``deadline`` is on (the caller's
    ``time.monotonic``).
    """
    late = 0
    while True:
        remaining = deadline - now()
        if remaining <= 0:
            late += 1
            if late > LATE_FRAMES:
                return
        msg = bus.recv(timeout=max(remaining, 0.0))
        if msg is None:
            return
        if bool(msg.is_extended_id) == extended:
            yield msg
