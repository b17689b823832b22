"""Everything about Dynamixel servos in one folder: the bus (:mod:`.bus`) and its tables (:mod:`.tables`).

Reached through ``load_backend("dynamixel")``; what differs from other vendors in calibration rules is the
vendor's declaration in :mod:`robocal.core.vendors`.
"""

from __future__ import annotations

from .bus import DynamixelBus
from .tables import DYNAMIXEL_MODELS, SIGNED_BYTES, X_TABLE

__all__ = ["DYNAMIXEL_MODELS", "SIGNED_BYTES", "X_TABLE", "DynamixelBus"]
