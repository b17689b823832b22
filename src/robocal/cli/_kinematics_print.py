"""What ``robocal kinematics identify`` prints: the parameter table, errors, reasons and the files written."""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

from rich.table import Table

from ._common import console, print_warnings

if TYPE_CHECKING:
    from ..workflows.kinematics import job as wf

__all__ = ["print_identification", "print_images"]

NORM_MEAN_PER_SIGMA = 2.0 * math.sqrt(2.0 / math.pi)
"""Mean length of a 3-D isotropic Gaussian error per its σ per axis (≈ 1.596)."""


def _fmt(value: float | None, unit: str) -> str:
    if value is None:  # a σ the covariance could not give
        return "—"
    if unit == "px":
        return f"{value:+.2f} px"
    return f"{value * 1e3:+.3f} mm" if unit == "m" else f"{math.degrees(value):+.4f}°"


def _stats(s: dict[str, float] | None, unit: str = "mm") -> str:
    if s is None:
        return "—"
    if unit == "mm" and s["max"] < 0.01:  # noise-free data: micrometres say more than 0.000 mm
        return f"mean {s['mean'] * 1e3:.3f} µm, max {s['max'] * 1e3:.3f} µm"
    return f"mean {s['mean']:.3f} {unit}, max {s['max']:.3f} {unit}"


def _print_parameters(rep: Mapping[str, Any]) -> None:
    """The identified parameters with their σ, one row each (the unidentifiable ones are listed apart)."""
    table = Table("parameter", "estimate", "± σ", box=None, pad_edge=False)
    for p in rep["parameters"]:
        if p["identified"]:
            table.add_row(p["name"], _fmt(p["estimate"], p["unit"]), _fmt(p["sigma"], p["unit"]).lstrip("+"))
    console.print(table)


def _print_unidentifiable(rep: Mapping[str, Any]) -> None:
    if rep["unidentifiable"]:
        console.print(f"not identifiable ({len(rep['unidentifiable'])}, kept nominal):")
        for u in rep["unidentifiable"]:
            console.print(f"  {u['name']}: {u['reason']}")


def _print_files(
    urdf_out: Path | None, report_out: Path | None, rep: Mapping[str, Any], warnings: Sequence[str], about: str
) -> int:
    """The files written (``about`` follows the report's name), then the warnings; the exit code."""
    if urdf_out is not None:
        offsets = "the zero offsets in the joint map" if "joint_map" in rep else "zero offsets folded in"
        console.print(f"wrote {urdf_out} (joint origins, {offsets})")
    if "joint_map" in rep:
        console.print(f"wrote {rep['joint_map']['file']} (joint map with the zero offsets; the URDF leaves them out)")
    if "ur_yaml" in rep:
        console.print(f"wrote {rep['ur_yaml']} (ur_description kinematics)")
    if report_out is not None:
        console.print(f"wrote {report_out}{about}")
    return print_warnings(warnings)


def print_identification(result: wf.IdentifyResult) -> int:
    """Print the identified parameters, validation and warnings; return the exit code (0 ok, 1 warnings)."""
    from ..workflows.kinematics import job as wf

    rep = result.report
    _print_parameters(rep)
    obs = rep["observability"]
    console.print(
        f"rank {rep['rank']} of {rep['unknowns']} unknowns; condition number {obs['condition']:.1f}, "
        f"O1 {obs['O1']:.3g}, O3 {obs['O3']:.3g}"
    )
    _print_unidentifiable(rep)
    err = rep["errors_mm"]
    console.print(
        f"fit poses ({rep['poses']['fit']}): nominal {_stats(err['fit']['nominal'])} → corrected "
        f"{_stats(err['fit']['corrected'])}"
    )
    if rep["poses"]["validation"]:
        nominal = err["validation"]["nominal"]
        console.print(
            f"validation poses ({rep['poses']['validation']}): "
            + (f"nominal {_stats(nominal)} → " if nominal else "")
            + f"corrected {_stats(err['validation']['corrected'])}"
        )
        noise = err.get("noise_per_axis")
        if noise is not None and noise >= 0.005:
            console.print(
                f"  (against the measured points: the marker noise, {noise:.2f} mm per axis as the fit estimates it, "
                f"alone gives a mean of about {NORM_MEAN_PER_SIGMA * noise:.2f} mm)"
            )
    predicted = err.get("predicted_rms")
    if predicted is not None:
        console.print(
            f"predicted error at new poses from the fit's covariance: RMS {predicted:.3f} mm over "
            f"{wf.PREDICTION_POSES} random poses inside the limits (the encoders' own resolution comes on top)"
        )
    if rep["dh_like"] is not None:
        dh = rep["dh_like"]
        held = ", ".join(dh["held_joints"]) or "none"
        console.print(
            f"DH-like fit (no tilt towards a parallel neighbour for: {held}): fit {_stats(dh['errors_mm']['fit'])}, "
            f"validation {_stats(dh['errors_mm']['validation'])}"
            + (
                " — DH is biased on parallel-axis arms; this floor stays with perfect data"
                if dh["held_joints"]
                else ""
            )
        )
    return _print_files(result.urdf_out, result.report_out, rep, result.warnings, "")


def print_images(result: object) -> int:
    """Print an image identification (``--kind tag``); return the exit code (0 ok, 1 warnings)."""
    from ..workflows.kinematics.vision import ImageIdentifyResult

    assert isinstance(result, ImageIdentifyResult)
    rep = result.report
    _print_parameters(rep)
    on_tool = "T_target_base" in rep
    frames = (
        ("target place", "camera", "target place T_target_base and camera mounting T_tip_camera")
        if on_tool
        else ("camera pose", "target", "camera pose T_cam_base and target mounting T_tip_target")
    )
    obs = rep["observability"]
    im = rep["images"]
    console.print(
        f"{im['with_target']} of {im['total']} images show the target; rank {rep['rank']} of {rep['unknowns']} "
        f"unknowns (base.* = {frames[0]}, tool.* = {frames[1]} on {rep['chain']['tip_link']}); condition number "
        f"{obs['condition']:.1f}"
    )
    _print_unidentifiable(rep)
    err = rep["reprojection_px"]
    fit_start, fit_end = _stats(err["fit"]["start"], "px"), _stats(err["fit"]["identified"], "px")
    console.print(f"reprojection, fit images: start {fit_start} → identified {fit_end}")
    if im["validation"]:
        val_start, val_end = _stats(err["validation"]["start"], "px"), _stats(err["validation"]["identified"], "px")
        console.print(
            f"reprojection, validation images ({im['validation']}): start {val_start} → identified {val_end}"
        )
    return _print_files(result.urdf_out, result.report_out, rep, result.warnings, f" ({frames[2]} in it)")
