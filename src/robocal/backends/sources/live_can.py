"""What every live CAN source shares: its joints, its open buses, its clock, a person as the operator.

:class:`RobstrideSource` (:mod:`.can`) and :class:`DamiaoSource` (:mod:`.damiao`) differ only in how a read asks
the motors for their state and what ``zero_sta`` is; opening, the sweep's hooks and closing are here, once.
"""

from __future__ import annotations

import time
from collections.abc import Sequence
from typing import Any

from .spec import JointSpec

__all__ = ["LiveCanSource"]


class LiveCanSource:
    """Live joint positions from CAN buses (one per channel), read passively; subclasses say how a read asks.

    Args:
        joints: The joints, in the sweep's order.
        buses: One open bus per channel, its motors named as the joints.
    """

    frame = "motor"

    def __init__(self, joints: Sequence[JointSpec], buses: Sequence[Any]) -> None:
        self.joints = tuple(joints)
        self.joint_names = tuple(j.name for j in self.joints)
        self.buses = list(buses)
        self._index = {n: i for i, n in enumerate(self.joint_names)}
        self._t0 = time.monotonic()

    @property
    def exhausted(self) -> bool:
        """A live robot never runs out."""
        return False

    def _now(self) -> float:
        """Seconds since the source was opened."""
        return time.monotonic() - self._t0

    def begin_sweep(self) -> None:
        """Nothing to do on a live robot (the operator is a person)."""

    def prompt_positive(self, joint: str) -> None:
        """Nothing to do on a live robot (the CLI shows the instruction)."""

    def close(self) -> None:
        """Close every bus (a Damiao arm's motors stay off)."""
        for bus in self.buses:
            bus.close()
        self.buses = []
