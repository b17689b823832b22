"""Exact conversions between the canonical joint map and other stacks' conventions.

Canonical (Lite / bar_robstride, Lite-Lowlevel-Python): ``q = direction·(raw − homing_offset)``, offset in the
motor frame. Every function here converts per joint, vectorised over arrays of joints, and the pairs are exact
inverses (up to one floating-point rounding). See ``docs/conventions.md`` for derivations.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .arrays import FloatArray

__all__ = [
    "LEROBOT_LEGACY_RAD_PER_TICK",
    "berkeley_offset_from_homing",
    "homing_from_berkeley_offset",
    "homing_from_joint_frame_offset",
    "homing_from_lerobot_legacy",
    "homing_from_transmission",
    "joint_frame_offset_from_homing",
    "lerobot_legacy_from_homing",
    "transmission_from_homing",
]


LEROBOT_LEGACY_RAD_PER_TICK = math.pi / 2048.0
"""LeRobot legacy DEGREE mode: ``deg = (±raw + h)·180/2048``, i.e. π/2048 rad per tick."""


def _f(x: ArrayLike) -> FloatArray:
    return np.asarray(x, dtype=np.float64)


def berkeley_offset_from_homing(direction: ArrayLike, homing_offset: ArrayLike) -> FloatArray:
    """Berkeley-Humanoid-Lite-Lowlevel joint-frame offset: ``off = direction·homing_offset``.

    Berkeley reads ``q = raw·direction − off``; with ``off = direction·h`` this equals the canonical
    ``direction·(raw − h)``.
    """
    out: FloatArray = _f(direction) * _f(homing_offset)
    return out


def homing_from_berkeley_offset(direction: ArrayLike, offset: ArrayLike) -> FloatArray:
    """Inverse of :func:`berkeley_offset_from_homing`: ``homing_offset = direction·off``."""
    out: FloatArray = _f(direction) * _f(offset)
    return out


def joint_frame_offset_from_homing(direction: ArrayLike, homing_offset: ArrayLike) -> FloatArray:
    """Joint-frame offset form ``q = direction·raw + offset``: ``offset = −direction·homing_offset``."""
    out: FloatArray = -_f(direction) * _f(homing_offset)
    return out


def homing_from_joint_frame_offset(direction: ArrayLike, offset: ArrayLike) -> FloatArray:
    """Inverse of :func:`joint_frame_offset_from_homing`: ``homing_offset = −direction·offset``."""
    out: FloatArray = -_f(direction) * _f(offset)
    return out


def transmission_from_homing(direction: ArrayLike, homing_offset: ArrayLike) -> tuple[FloatArray, FloatArray]:
    """ros2_control ``SimpleTransmission``: ``mechanical_reduction = direction``, ``offset = −direction·h``.

    SimpleTransmission maps actuator → joint as ``q = a/n + offset``. With ``n = direction`` (±1, so
    ``1/n = n``) and ``offset = −direction·h`` this is the canonical ``direction·(raw − h)``.

    Returns:
        ``(mechanical_reduction, offset)``, each shaped like the inputs.
    """
    d = _f(direction)
    return d.copy(), -d * _f(homing_offset)


def homing_from_transmission(
    mechanical_reduction: ArrayLike, offset: ArrayLike
) -> tuple[FloatArray, FloatArray]:
    """Inverse of :func:`transmission_from_homing`.

    Returns:
        ``(direction, homing_offset)`` with ``homing_offset = −offset·reduction`` (exact for reduction ±1).
    """
    n = _f(mechanical_reduction)
    return n.copy(), -_f(offset) * n


def homing_from_lerobot_legacy(
    drive_mode: ArrayLike, homing_offset_ticks: ArrayLike
) -> tuple[FloatArray, FloatArray, FloatArray]:
    """LeRobot legacy DEGREE calibration → canonical ``(direction, homing_offset_ticks, scale_rad_per_tick)``.

    Legacy: ``deg = (s·raw + h)·180/2048`` with ``s = −1`` if ``drive_mode`` else ``+1``; in rad
    ``q = (s·raw + h)·π/2048 = s·(π/2048)·(raw + s·h)``, so ``direction = s``, ``homing_offset = −s·h`` and
    ``scale = π/2048``.
    """
    s = np.where(_f(drive_mode) != 0, -1.0, 1.0)
    h = _f(homing_offset_ticks)
    scale = np.full(np.shape(s), LEROBOT_LEGACY_RAD_PER_TICK)
    return s, -s * h, scale


def lerobot_legacy_from_homing(
    direction: ArrayLike, homing_offset_ticks: ArrayLike
) -> tuple[NDArray[np.int64], FloatArray]:
    """Canonical (scale π/2048) → LeRobot legacy ``(drive_mode, homing_offset)``; inverse of the above."""
    d = _f(direction)
    drive_mode = (d < 0).astype(np.int64)
    return drive_mode, -d * _f(homing_offset_ticks)
