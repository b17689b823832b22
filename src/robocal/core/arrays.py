"""The array type aliases every robocal module uses (float64, int64 and bool numpy arrays; a 3-vector tuple).

One definition so that a signature reads the same everywhere; numpy alone, importable from a control loop.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

__all__ = ["BoolArray", "FloatArray", "IntArray", "Vec3"]

FloatArray = NDArray[np.float64]
"""A float64 array (any shape); units and frame are given by the name that holds it."""

IntArray = NDArray[np.int64]
"""An int64 array (any shape), e.g. raw encoder ticks."""

BoolArray = NDArray[np.bool_]
"""A boolean array (any shape), e.g. a per-sample mask."""

Vec3 = tuple[float, float, float]
"""Three floats as a plain tuple (a URDF ``xyz``/``rpy``/``axis``, a centre of mass), for frozen dataclasses."""
