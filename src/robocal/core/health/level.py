"""Where a follower rests against its goal: the level of ``action − state`` on slow frames away from its extremes.

A position-controlled follower at rest stands where its goal is, up to its sag under gravity and its friction dead
band (either side): at every pose it rests in, the median of ``a(t−1) − s(t) − sag(t)`` is within a fraction of a
degree of zero. A disagreement at *every* pose is not physics: the recorded ``action`` and ``observation.state``
are not in one calibration frame (a calibration that changed between them, a column edited after the recording, a
follower whose goal and reading conversions differ). That is what a residual on "stable" frames sees
(huggingface/lerobot PR #3759). It is not what a calibration offset between two correctly working arms does
(their numbers agree; :mod:`.offsets`), and not what a grasp or a contact does (the follower held at one pose).

The level is therefore read per pose: the frames are put in bins of the follower's reading, and the level is the
bin median nearest zero when every bin's median has the same sign (0 otherwise), so a gripper closed on an object
or a follower pressed on the table at one pose does not move it.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..arrays import FloatArray

__all__ = ["RestLevel", "rest_level"]


@dataclass(frozen=True)
class RestLevel:
    """The follower's rest level on one joint (dataset units).

    Attributes:
        level: The bin median nearest zero (0 when the bins disagree in sign): what every pose shows.
        typical: The median of the bin medians: the estimate of the disagreement when ``level`` shows one.
        bins: ``(B, 3)``: per pose bin, its centre, median residual and frame count.
        frames: Frames used (slow, away from the follower's extremes, in a bin with enough frames).
    """

    level: float
    typical: float
    bins: tuple[tuple[float, float, int], ...]
    frames: int


def rest_level(
    action_prev: FloatArray,
    state: FloatArray,
    sag: FloatArray,
    slow: np.ndarray,
    edge: float,
    bin_width: float,
    min_bins: int = 3,
    min_frames: int = 10,
) -> RestLevel | None:
    """The rest level of one joint, or None when fewer than ``min_bins`` poses have ``min_frames`` frames.

    Args:
        action_prev: ``(N,)`` the leader's previous value ``a(t−1)`` (NaN at an episode's first frame).
        state: ``(N,)`` the follower's value.
        sag: ``(N,)`` the modelled rest residual (zeros where no model gives it).
        slow: ``(N,)`` bool, frames where the leader moved slowly.
        edge: Frames within this of the follower's extremes are left out (a stop or limit holds it there).
        bin_width: Width of a pose bin, the values' units.
        min_bins: Fewest populated bins for a level.
        min_frames: Frames a bin needs.
    """
    r = action_prev - state - sag
    ok = slow & np.isfinite(r) & (state > np.min(state) + edge) & (state < np.max(state) - edge)
    if not ok.any() or not bin_width > 0:
        return None
    s, r = state[ok], r[ok]
    index = np.floor((s - float(np.min(s))) / bin_width).astype(np.int64)
    bins = []
    for b in np.unique(index):
        inside = index == b
        if int(inside.sum()) >= min_frames:
            bins.append((float(np.median(s[inside])), float(np.median(r[inside])), int(inside.sum())))
    if len(bins) < min_bins:
        return None
    medians = np.array([b[1] for b in bins])
    same_sign = bool(np.all(medians > 0) or np.all(medians < 0))
    level = float(medians[np.argmin(np.abs(medians))]) if same_sign else 0.0
    return RestLevel(level, float(np.median(medians)), tuple(bins), sum(b[2] for b in bins))
