"""Everything about Feetech servos in one folder: the bus (:mod:`.bus`) and its tables (:mod:`.tables`).

Reached through ``load_backend("feetech")``; what differs from other vendors in calibration rules is the
vendor's declaration in :mod:`robocal.core.vendors`.
"""

from __future__ import annotations

from .bus import FeetechBus
from .tables import FEETECH_MODELS, SCS_TABLE, SIGN_BITS, STS_TABLE

__all__ = ["FEETECH_MODELS", "SCS_TABLE", "SIGN_BITS", "STS_TABLE", "FeetechBus"]
