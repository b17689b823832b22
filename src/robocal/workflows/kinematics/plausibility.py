"""Plausibility of ``kinematics identify``'s data and result: units, reach, corrections, residual against noise.

Before the fit, the measured points must be the arm's size (a factor such as 1000 names a unit mistake) and, in
the base frame, within the chain's reach (:func:`check_units`); a gauge's distance must be about the nominal
one (:func:`check_gauge`). After it, no correction may exceed what a URDF is plausibly off by (20 mm / 10° by
default, :func:`check_corrections`), and a residual far above the marker noise is a warning naming the poses that
carry it (:func:`residual_warnings`).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from ...core.arrays import IntArray
from ...core.kinematic_errors import ErrorModel
from ...core.kinematic_problem import Measurements, Problem
from ...errors import UsageError
from .fit import FitResult

__all__ = [
    "MAX_CORRECTION_DEG",
    "MAX_CORRECTION_MM",
    "NOISE_CEILING_MM",
    "check_bounds",
    "check_corrections",
    "check_gauge",
    "check_session",
    "check_units",
    "residual_warnings",
]


MAX_CORRECTION_MM = 20.0
"""Largest correction of a length (origin, tool point) a URDF is plausibly off by (``--max-correction-mm``)."""

MAX_CORRECTION_DEG = 10.0
"""Largest correction of an angle (tilt, zero offset) a URDF is plausibly off by (``--max-correction-deg``)."""

NOISE_CEILING_MM = 5.0
"""Marker noise per axis (mm) above which, with no ``--noise-mm`` stated, the residual is not noise."""

NOISE_FACTOR = 3.0
"""The residual per axis is far above the stated noise beyond this factor."""

OUTLIER_SIGMAS = 5.0
"""A pose whose error is beyond this many σ of the noise carries the residual (a 3-D Gaussian: p ≈ 1.5e-5)."""

OUTLIER_FLOOR_MM = 0.05
"""A pose is named only if its error is beyond this too (noise-free data leave ~1e-10 mm of rounding)."""

SPREAD_RATIO = 1.25
"""The measured points' spread may differ from the nominal arm's by this factor (either way) at most."""

UNIT_SCALES: tuple[tuple[float, str], ...] = (
    (1000.0, "millimetres under metre columns (name them x_mm, y_mm, z_mm)"),
    (100.0, "centimetres under metre columns (convert them to metres)"),
    (39.37, "inches under metre columns (convert them to metres)"),
    (1e-3, "metres under millimetre columns (name them x, y, z)"),
    (1e-2, "metres as hundredths (convert them to metres)"),
)
"""Scale factors of the measured points against the arm that name a unit mistake."""


def check_units(model: ErrorModel, data: Measurements, *, frame: str, source: str) -> None:
    """The measured points must be the arm's size, and (base frame) within its reach.

    Args:
        model: The nominal :class:`~robocal.core.kinematic_errors.ErrorModel` (tool point set).
        data: The session.
        frame: ``base`` or ``tracker``.
        source: The session file, for messages.

    Raises:
        UsageError: The spread of the points is not the nominal arm's (a unit mistake named when the factor is
            one), or a point is farther from the base than the chain reaches.
    """
    if data.p_world_m is None or data.n_poses < 2:
        return
    nominal = model.points(data.q_rad)
    spread_nom = float(np.sqrt(np.mean(np.sum((nominal - nominal.mean(axis=0)) ** 2, axis=1))))
    p = data.p_world_m
    spread = float(np.sqrt(np.mean(np.sum((p - p.mean(axis=0)) ** 2, axis=1))))
    if spread_nom > 1e-3:
        ratio = spread / spread_nom
        if not 1.0 / SPREAD_RATIO <= ratio <= SPREAD_RATIO:
            unit = next((text for f, text in UNIT_SCALES if abs(math.log(ratio / f)) < math.log(SPREAD_RATIO)), None)
            cause = (
                f"the units are wrong: these look like {unit}"
                if unit is not None
                else "the data do not fit this URDF: check the columns (joints and x, y, z in their places), "
                "--tool-xyz, --tip-link, and that the URDF is this arm's"
            )
            raise UsageError(
                f"{source}: the measured points spread {spread * 1e3:.4g} mm about their centre, the nominal arm's "
                f"points at the same readings {spread_nom * 1e3:.4g} mm (×{ratio:.3g}): {cause}"
            )
    if frame != "base":
        return
    chain = model.chain
    reach = sum(math.sqrt(sum(v * v for v in j.origin_xyz_m)) for j in chain.joints)
    reach += float(np.linalg.norm(model.T_tip_tool[:3, 3]))
    reach += sum(abs(j.upper or 0.0) for j in chain.movable if j.type == "prismatic")
    dist = np.linalg.norm(p - model.T_world_base[:3, 3], axis=1)
    far = int(np.argmax(dist))
    limit = SPREAD_RATIO * reach + MAX_CORRECTION_MM * 1e-3
    if float(dist[far]) > limit:
        raise UsageError(
            f"{source}: pose {far + 1}'s point is {dist[far] * 1e3:.4g} mm from the base, farther than the chain "
            f"reaches ({reach * 1e3:.4g} mm): the points are not in the base frame (--frame tracker if they are "
            "in the tracker's own frame) or not in metres"
        )


def check_gauge(model: ErrorModel, data: Measurements, *, source: str) -> None:
    """The gauge distance must be about the nominal arm's distance between the sockets.

    Raises:
        UsageError: ``--gauge-mm`` differs from it by more than a factor 2.
    """
    if data.kind != "gauge" or data.distance_m is None or data.group is None or data.groups() != (0, 1):
        return
    p = model.points(data.q_rad)
    nominal = float(np.linalg.norm(p[data.group == 0].mean(axis=0) - p[data.group == 1].mean(axis=0)))
    if nominal > 0.0 and not 0.5 <= data.distance_m / nominal <= 2.0:
        raise UsageError(
            f"{source}: --gauge-mm {data.distance_m * 1e3:g}, but the nominal arm puts sockets A and B "
            f"{nominal * 1e3:.4g} mm apart: the distance must be in millimetres (or the sockets are swapped)"
        )


def check_corrections(result: FitResult, model: ErrorModel, *, max_mm: float, max_deg: float) -> None:
    """Refuse a fit whose corrections are beyond what a URDF is plausibly off by.

    A length is beyond the bound past ``max_mm``. An angle is past ``max_deg`` *and* when it moves the tool point
    by more than ``max_mm`` at some pose of the session: a zero offset of a joint whose axis passes close to the
    marker stands in for the marker's place around it (a wrist roll 12 mm from the marker turns 5° per mm), and
    is not judged by its size alone. Point data only: with touch or gauge data the contact points take up the
    arm's overall placement, and a correction the few contacts see weakly trades with them.

    Args:
        result: The fit.
        model: Its error model.
        max_mm: Largest length correction (mm).
        max_deg: Largest angle correction (degrees).

    Raises:
        UsageError: Corrections beyond the bounds, the largest named.
    """
    over: list[tuple[float, str]] = []
    problem = result.problem
    if not isinstance(problem, Problem) or problem.data.kind != "points":
        return  # contact points take up the arm's placement: a weakly seen correction trades with them
    _, J = problem.residuals_and_jacobian(problem.initial_theta())
    n = problem.data.n_poses
    # how far each unknown moves the tool point per unit, at the pose where it moves it most (m per m or rad)
    lever = np.linalg.norm(J[: 3 * n].reshape(n, 3, -1), axis=1).max(axis=0) if n else np.zeros(J.shape[1])
    for i in result.estimated:
        if i >= len(result.problem.free):
            continue  # a contact point
        p = model.parameters[result.problem.free[i]]
        if p.group == "base":
            continue  # a registration, any size
        v = float(result.theta[i])
        if p.unit == "m" and abs(v) > max_mm * 1e-3:
            over.append((abs(v) / (max_mm * 1e-3), f"{p.name} by {v * 1e3:+.4g} mm"))
        elif p.unit == "rad" and abs(v) > math.radians(max_deg) and abs(v) * lever[i] > max_mm * 1e-3:
            over.append((abs(v) / math.radians(max_deg), f"{p.name} by {math.degrees(v):+.4g}°"))
    if not over:
        return
    over.sort(reverse=True)
    named = ", ".join(text for _, text in over[:4]) + (f" and {len(over) - 4} more" if len(over) > 4 else "")
    raise UsageError(
        f"the fit corrects {named}: beyond the {max_mm:g} mm / {max_deg:g}° a URDF is plausibly off by "
        "(--max-correction-mm, --max-correction-deg): the data do not fit this URDF; check the joint columns "
        "(order, units, the zero of each joint), the points' units and frame, --tool-xyz, --tip-link, and that "
        "the URDF is this arm's"
    )


def check_bounds(max_mm: float, max_deg: float) -> None:
    """``--max-correction-mm`` and ``--max-correction-deg`` as given, checked.

    Raises:
        UsageError: Not a positive number (degrees: at most 180).
    """
    if not (math.isfinite(max_mm) and max_mm > 0):
        raise UsageError(f"--max-correction-mm must be a positive number, got {max_mm}")
    if not (math.isfinite(max_deg) and 0 < max_deg <= 180):
        raise UsageError(f"--max-correction-deg must be a number of degrees in (0, 180], got {max_deg}")


def residual_warnings(
    result: FitResult, train_rows: IntArray, *, noise_m: float | None, source: str
) -> tuple[list[str], dict[str, Any]]:
    """Compare the fit's residual with the marker noise (stated, or what the fit estimates) and name its poses.

    The noise per axis the fit estimates is ``sqrt(Σ r² / (3 N − rank))``. It is far above the stated noise
    beyond :data:`NOISE_FACTOR` times it, or with none stated above :data:`NOISE_CEILING_MM`; a pose whose error
    is beyond :data:`OUTLIER_SIGMAS` σ (stated, or a robust σ from the median error) and
    :data:`OUTLIER_FLOOR_MM` carries the residual.

    Args:
        result: The fit (point, touch or gauge).
        train_rows: The data row (0-based) of each fitted pose.
        noise_m: The marker noise per axis the user stated (m), or None.
        source: The session file, for messages.

    Returns:
        Warnings and the report's residual block.
    """
    e = result.train_errors_m
    dof = 3 * e.size - result.identifiability.rank
    fit_noise = math.sqrt(float(np.sum(e**2)) / dof) if dof > 0 else math.nan
    robust = float(np.median(e)) / 1.538  # the median length of a 3-D Gaussian error is 1.538 σ
    sigma = noise_m if noise_m is not None else robust
    warnings: list[str] = []
    far = np.flatnonzero(e > max(OUTLIER_SIGMAS * sigma, OUTLIER_FLOOR_MM * 1e-3))
    limit = NOISE_FACTOR * noise_m if noise_m is not None else NOISE_CEILING_MM * 1e-3
    worst = np.argsort(-e)[:5]

    def poses(idx: IntArray) -> str:
        shown = ", ".join(f"pose {int(train_rows[i]) + 1} ({e[i] * 1e3:.3g} mm)" for i in idx[:5])
        return shown + (f" and {idx.size - 5} more" if idx.size > 5 else "")

    if noise_m is not None:
        stated = (
            f"the stated marker noise ({noise_m * 1e3:.3g} mm; {NOISE_FACTOR:g}× is {limit * 1e3:.3g} mm): the "
            "marker is noisier than stated, the joint readings coarser (4096 ticks a turn: about 0.1 mm at the "
            "tool), or the data do not fit this URDF"
        )
    else:
        stated = f"any marker's noise ({limit * 1e3:.3g} mm): the data do not fit this URDF"
    if math.isfinite(fit_noise) and fit_noise > limit:
        share = float(np.sum(e[worst] ** 2) / np.sum(e**2))
        warnings.append(
            f"the residual, {fit_noise * 1e3:.3g} mm per axis, is far above {stated}; the poses that carry most "
            f"of it ({share:.0%}): {poses(worst)} in {source}"
        )
    elif far.size:
        far = far[np.argsort(-e[far])]
        warnings.append(
            f"{far.size} {'pose carries' if far.size == 1 else 'poses carry'} an error beyond {OUTLIER_SIGMAS:g} σ "
            f"of the marker noise ({sigma * 1e3:.3g} mm per axis{'' if noise_m is not None else ' as the fit finds it'})"
            f": {poses(far)} in {source}; a marker dropout, a misread joint or a pose taken before the arm "
            "settled: re-measure or remove them (or fit with --huber)"
        )
    report = {
        "noise_per_axis_mm": None if not math.isfinite(fit_noise) else fit_noise * 1e3,
        "stated_noise_mm": None if noise_m is None else noise_m * 1e3,
        "outlier_poses": [int(train_rows[i]) + 1 for i in far],
    }
    return warnings, report


def check_session(model: ErrorModel, data: Measurements, *, frame: str, source: str) -> None:
    """:func:`check_units` and :func:`check_gauge` of a session (exact copies merged)."""
    check_units(model, data, frame=frame, source=source)
    check_gauge(model, data, source=source)
