"""How a Dynamixel X servo's position loop turns its gain registers into stiffness, and its factory gains.

One formula for everything that needs the servo's stiffness: the simulated firmware (:mod:`.sim`), the teleoperation
simulator and the dataset health check (a follower's sag under gravity). Reached through
``load_backend("dynamixel.position_loop")`` (:data:`POSITION_LOOP`; the vendor's declaration names it: ``VendorSpec.position_loop``).

ROBOTIS' position loop (e-Manual, "Position PID Gain"): ``KP = Position_P_Gain / 128`` and
``KD = Position_D_Gain / 16`` in current (or PWM) units per tick of error and per tick/ms; the torque of one unit
is ``current_unit · kt``.
"""

from __future__ import annotations

import math

from ..servo_ratings import RATINGS, PositionLoop
from .tables import X_TABLE

__all__ = ["POSITION_LOOP", "factory_position_gains", "position_gains_nm_rad"]


def position_gains_nm_rad(model: str, p: float, d: float, ticks_per_turn: int = 4096) -> tuple[float, float]:
    """The position loop's stiffness and damping for ``Position_P_Gain`` ``p`` and ``Position_D_Gain`` ``d``.

    Args:
        model: Servo model (``"xl330-m288"``), a key of :data:`robocal.backends.servo_ratings.RATINGS`.
        p: ``Position_P_Gain``.
        d: ``Position_D_Gain``.
        ticks_per_turn: Encoder ticks per turn.

    Returns:
        ``(kp, kd)``: N·m/rad and N·m·s/rad.

    Raises:
        KeyError: No rating for ``model``.
    """
    r = RATINGS[model]
    unit_nm = r.current_unit_a * r.kt_nm_a
    per_rad = ticks_per_turn / math.tau
    return p / 128 * unit_nm * per_rad, d / 16 * unit_nm * per_rad * 0.001


def factory_position_gains(model: str) -> tuple[int, int, int]:
    """``(Position_P_Gain, Position_I_Gain, Position_D_Gain)`` as the servo leaves the factory (its e-Manual).

    Raises:
        KeyError: No factory table for ``model``.
    """
    from ..sim.servo_defaults import FACTORY_DEFAULTS

    table = FACTORY_DEFAULTS[model]
    regs = ("Position_P_Gain", "Position_I_Gain", "Position_D_Gain")
    p, i, d = (table.get(X_TABLE[r][0], (2, 0))[1] for r in regs)
    return p, i, d


POSITION_LOOP = PositionLoop(position_gains_nm_rad, factory_position_gains)
"""The two above, as the backend registry hands them out."""
