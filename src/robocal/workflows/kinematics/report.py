"""The parts of an identification report that ``identify`` and ``identify_images`` share, and its writing.

Both reports hold, in this order: the chain (:func:`chain_summary`), what was measured, the rank /
observability / fit block (:func:`fit_summary`), the errors before and after, the parameters
(:func:`parameter_rows`), the unidentifiable / joint offsets / corrected origins block (:func:`model_summary`).
Each identifier adds its own keys around these. :func:`write_identify_files` then adds the exports and writes
the corrected URDF, the exports and the JSON report, in that order, each atomically.
"""

from __future__ import annotations

import json
import math
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from ...core.arrays import FloatArray
from ...core.chain import SerialChain
from ...core.kinematic_errors import ErrorModel
from ...fileio import atomic_write_bytes, atomic_write_text
from ...formats.urdf import UrdfDocument
from ...formats.urdf_chain import corrected_urdf_bytes
from .export import ExportPaths, prepare_exports, write_exports
from .fit import FitResult, PriorSigmas
from .request import IdentifyOutputs

__all__ = [
    "CONDITION_LIMIT",
    "chain_summary",
    "condition_warnings",
    "error_stats",
    "finite",
    "fit_summary",
    "model_summary",
    "origin_changed",
    "parameter_rows",
    "prior_summary",
    "write_identify_files",
]

CONDITION_LIMIT = 100.0
"""Above this condition number of the identification Jacobian the poses are too alike: a warning."""


def condition_warnings(result: FitResult, advice: str) -> list[str]:
    """A warning ending in ``advice`` when the fit's condition number is above :data:`CONDITION_LIMIT`."""
    condition = result.identifiability.observability.condition
    if condition > CONDITION_LIMIT:
        return [f"condition number {condition:.0f} is above 100: {advice}"]
    return []


def error_stats(errors: FloatArray, scale: float = 1.0) -> dict[str, float] | None:
    """Mean and maximum of per-pose errors times ``scale`` (``1e3`` for m → mm); None without poses."""
    if errors.size == 0:
        return None
    return {"mean": float(errors.mean() * scale), "max": float(errors.max() * scale)}


def chain_summary(chain: SerialChain) -> dict[str, Any]:
    """The report's ``chain``: base link, tip link and the movable joints in order."""
    return {
        "base_link": chain.base_link,
        "tip_link": chain.tip_link,
        "joints": list(chain.joint_names),
    }


def fit_summary(result: FitResult, unknowns: int, prior: dict[str, Any] | None) -> dict[str, Any]:
    """The report's ``rank``, ``unknowns``, ``observability`` and ``fit`` (method, loss, convergence, ``prior``)."""
    ident = result.identifiability
    return {
        "rank": ident.rank,
        "unknowns": unknowns,
        "observability": {
            "O1": ident.observability.O1,
            "condition": ident.observability.condition,
            "O3": ident.observability.O3,
            "O5": ident.observability.O5,
        },
        "fit": {
            "method": result.method,
            "loss": result.loss,
            "evaluations": result.iterations,
            "converged": result.success,
            "prior": prior,
        },
    }


def prior_summary(prior: PriorSigmas | None, *, noise: bool) -> dict[str, Any] | None:
    """The report's ``fit.prior``: the prior's σ in mm and degrees (and its ``noise_mm`` when ``noise``), or None."""
    if prior is None:
        return None
    summary: dict[str, Any] = {
        "length_mm": prior.length_m * 1e3,
        "angle_deg": math.degrees(prior.angle_rad),
        "offset_deg": math.degrees(prior.offset_rad),
    }
    if noise:
        summary["noise_mm"] = None if prior.noise_m is None else prior.noise_m * 1e3
    return summary


def parameter_rows(result: FitResult, names: Sequence[str], units: Sequence[str]) -> list[dict[str, Any]]:
    """The report's ``parameters``: name, unit, estimate, σ (None where not finite) and whether identified.

    Args:
        result: The fit.
        names: The name of each unknown, in the problem's order.
        units: The unit of each unknown (``m``, ``rad``, ``px``), in the same order.
    """
    ident = result.identifiability
    return [
        {
            "name": name,
            "unit": units[i],
            "estimate": float(result.theta[i]),
            "sigma": float(result.sigma[i]) if math.isfinite(result.sigma[i]) else None,
            "identified": i in ident.base,
        }
        for i, name in enumerate(names)
    ]


def model_summary(result: FitResult, model: ErrorModel, corrected: SerialChain) -> dict[str, Any]:
    """The report's ``unidentifiable``, ``joint_offsets`` (read from ``result.x``) and ``corrected_origins``."""
    return {
        "unidentifiable": [
            {"name": u.name, "reason": u.reason, "same_as": [[n, c] for n, c in u.same_as]}
            for u in result.identifiability.unidentifiable
        ],
        "joint_offsets": model.offsets(result.x),
        "corrected_origins": {
            j.name: {"xyz": list(j.origin_xyz_m), "rpy": list(j.origin_rpy_rad)} for j in corrected.movable
        },
    }


def origin_changed(old: SerialChain, new: SerialChain) -> dict[str, bool]:
    """For each movable joint of ``new``: whether its origin differs from ``old``'s (by more than 1e-12)."""
    before = {j.name: (*j.origin_xyz_m, *j.origin_rpy_rad) for j in old.movable}
    return {
        j.name: any(
            abs(a - b) > 1e-12
            for a, b in zip(before[j.name], (*j.origin_xyz_m, *j.origin_rpy_rad), strict=True)
        )
        for j in new.movable
    }


def finite(value: Any) -> Any:
    """``value`` with NaN and ±inf replaced by None, dicts and lists walked (JSON has no such numbers)."""
    if isinstance(value, dict):
        return {k: finite(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [finite(v) for v in value]
    if isinstance(value, float) and not math.isfinite(value):
        return None
    return value


def write_identify_files(
    doc: UrdfDocument,
    chain: SerialChain,
    model: ErrorModel,
    result: FitResult,
    paths: ExportPaths,
    report: dict[str, Any],
    warnings: list[str],
    outputs: IdentifyOutputs,
) -> tuple[Path | None, Path | None]:
    """Add the exports to ``report`` and ``warnings``, then write the URDF, the exports and the JSON report.

    Everything is prepared before the first write; each file is written atomically.

    Args:
        doc: The URDF the chain was read from (``paths.out`` is this document with corrected origins).
        chain: The nominal chain.
        model: The fitted error model.
        result: The fit (its ``x`` is applied).
        paths: Where to write (checked by :func:`robocal.workflows.kinematics.export.check_export_paths`).
        report: The report; updated in place with the exports' keys.
        warnings: The report's warnings list; extended in place with the exports' warnings.
        outputs: The request's outputs: the joint map the readings went through, its motor ids, the UR hash.

    Returns:
        The corrected URDF and the report written, each None when not asked for.
    """
    exports = prepare_exports(model, result.x, paths, joint_map=outputs.joint_map, ur_hash=outputs.ur_hash)
    report.update(exports.report)
    warnings += exports.warnings
    urdf_bytes = (
        corrected_urdf_bytes(doc, exports.urdf_chain, origin_changed(chain, exports.urdf_chain))
        if paths.out
        else None
    )
    report_text = json.dumps(finite(report), indent=2, allow_nan=False) + "\n"
    written_urdf = atomic_write_bytes(paths.out, urdf_bytes) if paths.out and urdf_bytes is not None else None
    write_exports(exports, paths, outputs.joint_map_ids)
    written_report = atomic_write_text(paths.report, report_text) if paths.report else None
    return written_urdf, written_report
