"""How a Feetech STS servo's position loop turns its gain registers into stiffness, and its factory gains.

One formula for everything that needs the servo's stiffness: the simulated firmware (:mod:`.sim`), the teleoperation
simulator and the dataset health check (a follower's sag under gravity). Reached through
``load_backend("feetech.position_loop")`` (:data:`POSITION_LOOP`; the vendor's declaration names it: ``VendorSpec.position_loop``).

The scaling is robocal's model of the firmware (docs/sim.md): ``P/1024`` of the stall torque per tick of position
error, ``D·0.005`` of the stall torque per rad/s.
"""

from __future__ import annotations

import math

from ..servo_ratings import RATINGS, PositionLoop
from .tables import STS_TABLE

__all__ = ["POSITION_LOOP", "factory_position_gains", "position_gains_nm_rad"]


def position_gains_nm_rad(model: str, p: float, d: float, ticks_per_turn: int = 4096) -> tuple[float, float]:
    """The position loop's stiffness and damping for ``P_Coefficient`` ``p`` and ``D_Coefficient`` ``d``.

    Args:
        model: Servo model (``"sts3215"``), a key of :data:`robocal.backends.servo_ratings.RATINGS`.
        p: ``P_Coefficient``.
        d: ``D_Coefficient``.
        ticks_per_turn: Encoder ticks per turn.

    Returns:
        ``(kp, kd)``: N·m/rad and N·m·s/rad.

    Raises:
        KeyError: No rating for ``model``.
    """
    stall_nm = RATINGS[model].stall_torque_nm
    return p / 1024 * stall_nm * ticks_per_turn / math.tau, d * 0.005 * stall_nm


def factory_position_gains(model: str) -> tuple[int, int, int]:
    """``(P, I, D)`` as the servo leaves the factory (``P_Coefficient`` 32, ``I`` 0, ``D`` 32 on the STS3215).

    Raises:
        KeyError: No factory table for ``model``.
    """
    from ..sim.servo_defaults import FACTORY_DEFAULTS

    table = FACTORY_DEFAULTS[model]
    p, i, d = (table.get(STS_TABLE[r][0], (1, 0))[1] for r in ("P_Coefficient", "I_Coefficient", "D_Coefficient"))
    return p, i, d


POSITION_LOOP = PositionLoop(position_gains_nm_rad, factory_position_gains)
"""The two above, as the backend registry hands them out."""
