"""How far a correct follower's residual reaches towards each range end: the yardsticks of a pinned end.

A follower arriving at a range end moves towards it, and its friction dead band leaves it short of its goal on that
side only; the check (:mod:`.offsets`) judges each end against the frames that came the same way
(:func:`end_bands`) and, when the sag was fitted from the data, against the raw residual of those frames
(:func:`end_raw_caps`).
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

import numpy as np

from ..arrays import FloatArray
from .sag import last_direction

if TYPE_CHECKING:
    from .offsets import HealthConfig, JointData

__all__ = ["end_bands", "end_raw_caps"]


def end_bands(
    d: JointData, residual: FloatArray, slow: np.ndarray, band: float, cfg: HealthConfig
) -> tuple[float, float]:
    """``(lower, upper)``: how far a correct follower's residual reaches towards each range end.

    A follower arriving at an end moves towards it, and its friction dead band leaves it short of its goal on that
    side only (``sgn·(action − state) > 0``), a few tenths of a degree on an STS3215 at P 16 but up to 1.3° on an
    XL330 at its factory gain. The symmetric band of all slow frames holds both sides and the lag of slow moves;
    an end is judged against the frames that came the same way: the slow frames whose reading last moved (by
    more than ``near_deg / 2``) towards that end, away from the joint's extremes (a stop holds the follower
    there): ``median + max(floor, 4·1.4826·MAD)`` of ``sgn·residual`` (at least the floor) plus ``end_margin_deg``,
    at most the symmetric band. Fewer than 30 such frames: the symmetric band.
    """
    upd = d.units_per_deg
    direction = last_direction(d.state, d.episode, 0.5 * cfg.near_deg * upd)
    edge = 3.0 * upd
    inner = (d.state > float(np.min(d.state)) + edge) & (d.state < float(np.max(d.state)) - edge)
    ok = slow & inner & np.isfinite(residual)
    floor = cfg.band_floor_deg * upd
    out = []
    for sgn in (-1.0, 1.0):
        x = sgn * residual[ok & (direction == sgn)]
        if x.size < 30:
            out.append(band)
            continue
        med = float(np.median(x))
        half = max(floor, 4.0 * 1.4826 * float(np.median(np.abs(x - med))))
        out.append(min(band, max(floor, med + half) + cfg.end_margin_deg * upd))
    return out[0], out[1]


def end_raw_caps(d: JointData, slow: np.ndarray, cfg: HealthConfig) -> tuple[float, float]:
    """``(lower, upper)``: the largest raw residual ``sgn·(action(t−1) − state(t))`` towards each end elsewhere.

    Taken over the slow frames whose reading last moved towards that end, away from the joint's extremes (as in
    :func:`end_bands`), plus ``end_margin_deg``; ``-inf`` unless the sag was fitted from the data
    (``d.sag_fitted``). A fitted sag is fitted away from the extremes and extrapolated to them; this cap needs no
    sag model: a follower pinned at an end stands further from its leader than it did anywhere else while moving
    that way, whatever gravity does (on a Koch the sag is largest near the ends, at ±90°).
    """
    if not d.sag_fitted:
        return -math.inf, -math.inf
    upd = d.units_per_deg
    same = np.zeros(d.action.shape, dtype=bool)
    same[1:] = d.episode[1:] == d.episode[:-1]
    raw = np.full(d.action.shape, np.nan)
    raw[1:] = d.action[:-1] - d.state[1:]
    direction = last_direction(d.state, d.episode, 0.5 * cfg.near_deg * upd)
    edge = 3.0 * upd
    inner = (d.state > float(np.min(d.state)) + edge) & (d.state < float(np.max(d.state)) - edge)
    ok = slow & inner & same & np.isfinite(raw)
    out = []
    for sgn in (-1.0, 1.0):
        x = sgn * raw[ok & (direction == sgn)]
        out.append(float(np.max(x)) + cfg.end_margin_deg * upd if x.size >= 30 else -math.inf)
    return out[0], out[1]
