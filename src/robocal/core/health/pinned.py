"""A follower pinned while its leader goes on: the teleoperation check of the live monitor.

Checked every ``check_period_s`` (not every tick: the flag waits ``pin_time_s`` anyway), on plain floats of the
paired joints (a few microseconds a check; cheaper than a dozen numpy calls on arrays of 14).
"""

from __future__ import annotations

import math

from ..arrays import FloatArray
from .monitor_types import HealthFlag, MonitorConfig

__all__ = ["PinWatch"]


class PinWatch:
    """Flags a paired follower that stays still far from its leader.

    Per paired joint: since when the follower has stayed within ``pin_still_rad`` of one reading while it is more
    than ``pin_residual_rad`` from its leader; it is flagged once after ``pin_time_s``.

    Attributes:
        check_period_s: Time between two checks, s.
    """

    def __init__(self, config: MonitorConfig, check_period_s: float = 0.05) -> None:
        """The paired joints and their (empty) state."""
        n = len(config.joint_names)
        self._config = config
        self.check_period_s = check_period_s
        self._paired = [j for j in range(n) if config.leader_paired[j]]
        self._anchor = [math.nan] * n  # the follower reading it stays near (NaN: near its leader)
        self._since = [math.nan] * n  # since when, s
        self._flagged = [False] * n
        self._next_t = -math.inf

    def reset(self) -> None:
        """Forget every joint's state."""
        n = len(self._anchor)
        self._anchor = [math.nan] * n
        self._since = [math.nan] * n
        self._flagged = [False] * n
        self._next_t = -math.inf

    def check(self, t_s: float, q: FloatArray, q_leader: FloatArray) -> list[HealthFlag] | None:
        """The joints that became pinned at ``t_s`` (None when none did, or when this tick is not a check).

        Args:
            t_s: Time, s.
            q: Follower readings, shape ``(N,)``, rad.
            q_leader: Leader readings, shape ``(N,)``, rad (NaN: no reading; the joint starts over).
        """
        if t_s < self._next_t or not self._paired:
            return None
        self._next_t = t_s + self.check_period_s
        cfg = self._config
        residual, still, hold = cfg.pin_residual_rad, cfg.pin_still_rad, cfg.pin_time_s
        anchor, since, flagged = self._anchor, self._since, self._flagged
        found: list[HealthFlag] | None = None
        q_list, lead_list = q.tolist(), q_leader.tolist()  # floats: one call each instead of 2N numpy scalars
        for j in self._paired:
            qj = q_list[j]
            r = lead_list[j] - qj
            if not abs(r) > residual:  # near its leader again (or no reading)
                anchor[j] = math.nan
                flagged[j] = False
            elif not abs(qj - anchor[j]) <= still:  # far, and moved (or just got far): start over here
                anchor[j] = qj
                since[j] = t_s
                flagged[j] = False
            elif t_s - since[j] >= hold and not flagged[j]:
                flagged[j] = True
                found = found or []
                found.append(HealthFlag(t_s, cfg.joint_names[j], "pinned", r, residual))
        return found
