"""What must hold before ``identify --kind tag`` claims a number: the gates of the point path, for images.

Images taken at the same joint readings (on the same encoder ticks, ``--ticks``) are one pose: they show the
target's pose once, however many there are. So the images with the target must span at least ``k // 6 + 2``
distinct poses, where ``k`` is what the images could identify from well spread poses (each pose shows the
target's 6 pose numbers; :func:`robocal.workflows.kinematics.fit.structural_image_analysis`), and their fitted
share too; the held-out share is drawn among the distinct poses, so no held-out image repeats a fitted pose.
After the fit, the fitted images must reach that rank (:func:`robocal.workflows.kinematics.gates.check_rank`
names what they leave unseen), and the reprojection residual is judged against the corner noise: a noise per
axis above :data:`NOISE_LIMIT_PX`, images far above the rest, or held-out images reprojected far worse than the
fitted ones are warnings (exit 1) naming the images.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from ...core.arrays import FloatArray, IntArray
from ...core.chain import SerialChain
from ...errors import UsageError
from .gates import distinct_poses

__all__ = [
    "HELD_OUT_FACTOR",
    "NOISE_LIMIT_PX",
    "OUTLIER_FACTOR",
    "OUTLIER_FLOOR_PX",
    "ImageSplit",
    "residual_warnings",
    "split_images",
]

NOISE_LIMIT_PX = 2.0
"""Largest plausible corner noise per axis, pixels: detected corners of a focused, calibrated camera scatter by
a few tenths of a pixel (0.2 px on the simulated sessions); beyond 2 px the images, the joint readings, the
camera file or the target's size do not fit the model."""

OUTLIER_FACTOR = 5.0
"""An image whose RMS reprojection error exceeds this many times the median fitted image's (and
:data:`OUTLIER_FLOOR_PX`) is named (the median: one bad image cannot hide itself by raising the scale)."""

OUTLIER_FLOOR_PX = 0.5
"""Below this RMS an image is never named (a tiny residual may be many times a tinier one)."""

HELD_OUT_FACTOR = 3.0
"""Held-out images reprojected worse than this many times the fitted ones' RMS (and 0.5 px) mean the
identified model does not carry over to new poses (too few or too similar poses, a wrong joint reading)."""


@dataclass(frozen=True, eq=False)
class ImageSplit:
    """The images with the target, split into fitted and held-out ones by distinct pose.

    Attributes:
        train_rows: ``(N,)`` the fitted images (indices into the detected images, ascending).
        validation_rows: ``(M,)`` the held-out images (ascending).
        report: The report's ``plausibility`` block so far (images, distinct poses, the rank they need).
        warnings: What the user should know (repeated poses, no validation).
    """

    train_rows: IntArray
    validation_rows: IntArray
    report: dict[str, Any]
    warnings: tuple[str, ...]


def _check_distinct(n: int, images: int, rank: int, *, source: str, fitted: bool) -> None:
    """Refuse fewer than ``rank // 6 + 2`` distinct poses (6 numbers each: the target's pose)."""
    need = rank // 6 + 2
    if n >= need:
        return
    what = "distinct fitted" if fitted else "distinct"
    repeats = "" if n == images else f" ({images} images repeat {n} distinct {'pose' if n == 1 else 'poses'})"
    raise UsageError(
        f"too few poses: {source} has {n} {what} {'pose' if n == 1 else 'poses'} with the target{repeats}, "
        f"{6 * n} numbers (the target's pose in each) for the {rank} unknowns the images could identify; take "
        f"images at {need} or more different poses (20 or more for a useful result; robocal kinematics plan "
        "--kind tag chooses them)"
    )


def split_images(
    q_rad: FloatArray,
    chain: SerialChain,
    structural_rank: int,
    *,
    fraction: float,
    seed: int,
    ticks_per_turn: int,
    source: str,
) -> ImageSplit:
    """Count the distinct poses of the images with the target and hold a seeded share of them out.

    The share is drawn as ``identify --kind tag`` always drew it (a permutation of the poses by ``seed``,
    ``round(fraction · poses)`` of them held out), over distinct poses instead of images: with no pose repeated
    the split is the same as before.

    Args:
        q_rad: ``(N, n_q)`` the joint readings of the images with the target.
        chain: The chain (its joint types set the resolution).
        structural_rank: What the images could identify from well spread poses.
        fraction: Share of the distinct poses held out.
        seed: Seed of the split.
        ticks_per_turn: Encoder resolution poses are told apart at (0: exact readings).
        source: The session file, for messages.

    Raises:
        UsageError: Too few distinct poses in the session or in its fitted share.
    """
    n_images = int(q_rad.shape[0])
    first, pose = distinct_poses(q_rad, chain, ticks_per_turn)
    n_poses = int(first.size)
    _check_distinct(n_poses, n_images, structural_rank, source=source, fitted=False)
    order = np.random.default_rng(seed).permutation(n_poses)
    held = order[: round(fraction * n_poses)]
    in_val = np.isin(pose, held)
    train_rows, val_rows = np.flatnonzero(~in_val), np.flatnonzero(in_val)
    train_poses = n_poses - int(held.size)
    _check_distinct(train_poses, int(train_rows.size), structural_rank, source=source, fitted=True)
    warnings: list[str] = []
    if n_poses < n_images:
        warnings.append(
            f"{source}: {n_images} images with the target at {n_poses} distinct poses (the same encoder "
            "readings): the images of one pose count as one pose and are fitted or held out together"
        )
    if not val_rows.size:
        warnings.append(
            "not validated: no image held out; hold some out (--validate-fraction) to see how the identified "
            "model reprojects poses it was not fitted to"
        )
    report = {
        "images": n_images,
        "distinct_poses": {"fit": train_poses, "validation": int(held.size)},
        "ticks_per_turn": ticks_per_turn,
        "model_rank": structural_rank,
    }
    return ImageSplit(train_rows.astype(np.int64), val_rows.astype(np.int64), report, tuple(warnings))


def _rms(errors_px: FloatArray) -> float:
    return float(np.sqrt(np.mean(errors_px**2))) if errors_px.size else math.nan


def residual_warnings(
    train_px: FloatArray,
    validation_px: FloatArray,
    train_names: Sequence[str],
    validation_names: Sequence[str],
) -> tuple[list[str], dict[str, Any]]:
    """Judge the reprojection residual against the corner noise the fit shows and the held-out images.

    Args:
        train_px: RMS reprojection error per fitted image, pixels.
        validation_px: The same per held-out image.
        train_names: ``image N (file)`` per fitted image, for messages.
        validation_names: The same per held-out image.

    Returns:
        Warnings (empty when the residual is plausible) and the report's residual keys.
    """
    warnings: list[str] = []
    fit_rms = _rms(train_px)
    noise_px = fit_rms / math.sqrt(2.0)  # an image's RMS is over the corner's two axes
    if noise_px > NOISE_LIMIT_PX:
        warnings.append(
            f"the fitted images are reprojected with {fit_rms:.2f} px RMS ({noise_px:.2f} px per axis, more than "
            f"the {NOISE_LIMIT_PX:g} px a calibrated camera's corners scatter by): check the camera file (its "
            "image size and intrinsics), the target's size in --target, and the joint readings"
        )
    median = float(np.median(train_px)) if train_px.size else math.nan
    limit = max(OUTLIER_FACTOR * median, OUTLIER_FLOOR_PX)
    far = [f"{name} {e:.2f} px" for name, e in zip(train_names, train_px, strict=True) if e > limit]
    if far:
        warnings.append(
            f"{len(far)} fitted {'image is' if len(far) == 1 else 'images are'} reprojected more than "
            f"{OUTLIER_FACTOR:g}× the median image's {median:.2f} px: {', '.join(far)}; check those images' "
            "detections and joint readings, or fit with --huber"
        )
    val_rms = _rms(validation_px)
    held_limit = max(HELD_OUT_FACTOR * fit_rms, OUTLIER_FLOOR_PX)
    if validation_px.size and val_rms > held_limit:
        worst = int(np.argmax(validation_px))
        warnings.append(
            f"the held-out images are reprojected with {val_rms:.2f} px RMS, more than {HELD_OUT_FACTOR:g}× the "
            f"fitted ones' {fit_rms:.2f} px (worst: {validation_names[worst]} {validation_px[worst]:.2f} px): the "
            "identified model does not carry over to new poses; take more images at poses spread over the joint "
            "ranges (robocal kinematics plan --kind tag)"
        )
    report = {
        "noise_per_axis_px": noise_px,
        "noise_limit_px": NOISE_LIMIT_PX,
        "fit_rms_px": fit_rms,
        "validation_rms_px": None if not validation_px.size else val_rms,
        "far_images": len(far),
    }
    return warnings, report
