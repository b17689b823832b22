"""UR kinematics jobs: extract from a controller, correct offline, regenerate defaults, plot.

Sources (controller via the primary interface, a DH YAML, or a model + calibration deltas) → core correction
→ ur_description kinematics YAML (+ optional in-place update of an expanded URDF). Verification of the result
against the DH model is :mod:`robocal.workflows.ur.verify`.
"""

from __future__ import annotations

import os
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ...backends import load_backend, require
from ...core.arrays import FloatArray
from ...core.dh import DHParameters
from ...core.ur import (
    NominalDeviation,
    UrKinematics,
    check_rpy_convention,
    correct_chain,
    correct_kinematics,
    default_kinematics,
    deviation_from_nominal,
    nominal_dh,
    six_transforms,
    split_chain,
)
from ...errors import UsageError
from ...fileio import atomic_write_bytes, atomic_write_text, backup_paths, check_output_path, read_bytes
from ...formats.ur_kinematics import (
    kinematics_to_text,
    read_deltas,
    read_dh,
    require_ur_joints,
    urdf_with_origins,
    write_kinematics,
)
from ...formats.urdf import UrdfDocument

__all__ = [
    "CorrectionResult",
    "check_out_path",
    "correct",
    "defaults",
    "extract",
    "load_dh_input",
    "plot",
    "read_controller_dh",
]




@dataclass(frozen=True)
class CorrectionResult:
    """Outcome of extract / correct / defaults.

    Attributes:
        dh: The raw DH that was corrected.
        kinematics: The written content.
        out_path: The kinematics YAML written.
        urdf_out: The URDF written, if any.
        warnings: Warnings (e.g. calibration_status ≠ 2); non-empty means exit code 1.
    """

    dh: DHParameters
    kinematics: UrKinematics
    out_path: Path
    urdf_out: Path | None = None
    warnings: tuple[str, ...] = ()

    @property
    def deviation(self) -> NominalDeviation:
        """How far the written kinematics lie from the nominal ones of their model (the robot's own deltas)."""
        return deviation_from_nominal(self.kinematics)


def check_out_path(
    path: str | os.PathLike[str],
    what: str = "--out",
    inputs: Mapping[str, str | os.PathLike[str] | None] | None = None,
) -> Path:
    """Refuse an output path whose folder does not exist, that is a directory or one of ``inputs`` (exit 2)."""
    return check_output_path(path, what, inputs=inputs)


def load_dh_input(
    dh_path: str | os.PathLike[str] | None,
    model: str | None,
    deltas_path: str | os.PathLike[str] | None,
    *,
    warnings: list[str] | None = None,
) -> DHParameters:
    """The DH to work on: ``--dh FILE``, or ``--model MODEL`` (+ ``--deltas FILE``) = nominal + deltas.

    Args:
        dh_path: DH YAML.
        model: UR model for the nominal DH.
        deltas_path: Calibration deltas (YAML or ``calibration.conf``) added to the model's nominal DH.
        warnings: When given, warnings about the input (unknown YAML keys) are appended; the CLI turns
            them into ``warning:`` lines and exit code 1.

    Raises:
        UsageError: Neither or both forms given, or ``--deltas`` without ``--model``.
        FileFormatError: Malformed files (names the file and key).
    """
    if dh_path is not None and (model is not None or deltas_path is not None):
        raise UsageError("give either --dh FILE or --model MODEL [--deltas FILE], not both")
    if dh_path is not None:
        return read_dh(dh_path, warnings=warnings)
    if model is None:
        raise UsageError("missing DH input: give --dh FILE or --model MODEL [--deltas FILE]")
    nominal = nominal_dh(model)
    if deltas_path is None:
        return nominal
    return nominal + read_deltas(deltas_path, warnings=warnings)


def _check_urdf_pair(
    urdf_in: str | os.PathLike[str] | None,
    urdf_out: str | os.PathLike[str] | None,
    out: str | os.PathLike[str],
) -> None:
    if (urdf_in is None) != (urdf_out is None):
        raise UsageError("--urdf-in and --urdf-out must be given together")
    if urdf_in is not None and urdf_out is not None:
        check_out_path(out, "--out", {"--urdf-in": urdf_in})
        check_out_path(urdf_out, "--urdf-out")
        if Path(urdf_out).resolve() == Path(out).resolve():
            raise UsageError(f"--urdf-out {urdf_out} is the same file as --out; give the URDF its own path")
        doc = UrdfDocument.load(urdf_in)  # parse + validate before anything is written
        require_ur_joints(doc.model(), urdf_in)


def _check_connection(host: str, port: int, timeout_s: float) -> None:
    from ...backends.ur_primary import check_connection_args

    check_connection_args(host, port, timeout_s)


def correct(
    dh: DHParameters,
    out: str | os.PathLike[str],
    *,
    rpy: str = "urdf",
    urdf_in: str | os.PathLike[str] | None = None,
    urdf_out: str | os.PathLike[str] | None = None,
    warnings: tuple[str, ...] = (),
) -> CorrectionResult:
    """Correct a DH set and write the kinematics YAML (and optionally the URDF origins).

    Everything is validated (paths, URDF joints, finite values) and both files' contents are prepared before
    the first byte is written. With ``--urdf-in/--urdf-out`` the pair is all-or-nothing: the URDF is written
    first, then the YAML; if the YAML cannot be written, the URDF (and its ``.bak``) are put back as they were.
    """
    rpy = check_rpy_convention(rpy)
    out_path = check_out_path(out)
    _check_urdf_pair(urdf_in, urdf_out, out_path)
    kin = correct_kinematics(dh, rpy)
    yaml_text = kinematics_to_text(kin)  # raises (non-finite values) before anything is written
    if urdf_in is None or urdf_out is None:
        return CorrectionResult(dh, kin, atomic_write_text(out_path, yaml_text), None, warnings)
    urdf_kin = kin if rpy == "urdf" else correct_kinematics(dh, "urdf")
    urdf_bytes = urdf_with_origins(urdf_in, urdf_kin)
    kinematics_to_text(urdf_kin)  # the URDF's values are finite too
    urdf_written = _write_pair(Path(urdf_out), urdf_bytes, out_path, yaml_text)
    return CorrectionResult(dh, kin, out_path, urdf_written, warnings)


def _snapshot(path: Path) -> bytes | None:
    """The current bytes of ``path`` (None when it does not exist)."""
    if not path.exists():
        return None
    return read_bytes(path, "file to replace")


def _write_pair(urdf_out: Path, urdf_bytes: bytes, out_path: Path, yaml_text: str) -> Path:
    """Write the URDF, then the YAML; if the YAML fails, restore the URDF and its ``.bak`` and re-raise."""
    saved = {p: _snapshot(p) for p in (urdf_out, *backup_paths(urdf_out))}
    atomic_write_bytes(urdf_out, urdf_bytes)
    try:
        atomic_write_text(out_path, yaml_text)
    except BaseException as exc:
        problems: list[str] = []
        for p, old in saved.items():
            try:
                if old is None:
                    p.unlink(missing_ok=True)
                else:
                    atomic_write_bytes(p, old, backup=False)
            except (OSError, UsageError) as restore_exc:
                problems.append(f"{p}: {restore_exc}")
        if problems and isinstance(exc, Exception):
            raise UsageError(
                f"{exc}; and restoring the URDF failed ({'; '.join(problems)}): "
                f"{urdf_out} holds the new origins"
            ) from None
        raise
    return urdf_out


def extract(
    host: str,
    out: str | os.PathLike[str],
    *,
    port: int = 30001,
    timeout_s: float = 10.0,
    rpy: str = "urdf",
    urdf_in: str | os.PathLike[str] | None = None,
    urdf_out: str | os.PathLike[str] | None = None,
) -> CorrectionResult:
    """Read KinematicsInfo from a controller (primary interface), correct it and write the YAML.

    Paths are checked before connecting, so a typo costs no robot time.
    """
    rpy = check_rpy_convention(rpy)
    _check_connection(host, port, timeout_s)
    check_out_path(out)
    _check_urdf_pair(urdf_in, urdf_out, out)
    with load_backend("ur_primary")(host, port, timeout_s) as client:
        info = client.read_kinematics()
        warnings = tuple(client.warnings)
    return correct(info.dh, out, rpy=rpy, urdf_in=urdf_in, urdf_out=urdf_out, warnings=warnings)


def defaults(model: str, out: str | os.PathLike[str], *, rpy: str = "upstream") -> CorrectionResult:
    """Regenerate ur_description's ``default_kinematics.yaml`` for ``model`` (URSim nominal DH)."""
    rpy = check_rpy_convention(rpy)
    out_path = check_out_path(out)
    kin = default_kinematics(model, rpy)
    return CorrectionResult(nominal_dh(model), kin, write_kinematics(out_path, kin))


def read_controller_dh(host: str, *, port: int = 30001, timeout_s: float = 10.0) -> tuple[DHParameters, list[str]]:
    """The calibrated DH a controller reports (KinematicsInfo), with the reader's warnings (status ≠ 2).

    Raises:
        UsageError: Bad host/port/timeout.
        CalibTimeoutError, ProtocolError, DeviceError: As :class:`~robocal.backends.ur_primary.PrimaryClient`.
    """
    _check_connection(host, port, timeout_s)
    with load_backend("ur_primary")(host, port, timeout_s) as client:
        info = client.read_kinematics()
        return info.dh, list(client.warnings)


def _frame_origins(mats: FloatArray) -> FloatArray:
    T = np.eye(4)
    pts = [T[:3, 3].copy()]
    for M in mats:
        T = T @ M
        pts.append(T[:3, 3].copy())
    return np.array(pts)


def plot(dh: DHParameters, out: str | os.PathLike[str], *, title: str | None = None) -> Path:
    """Draw the split DH model (arm links possibly far away) and the corrected model, at q = 0.

    Args:
        dh: Raw DH.
        out: PNG (or any matplotlib format) path; its folder must exist.
        title: Optional figure title.

    Returns:
        The written path.
    """
    out_path = check_out_path(out)
    split_pts = _frame_origins(split_chain(dh))
    corrected = six_transforms(correct_chain(dh))
    corr_pts = _frame_origins(corrected)
    require("matplotlib", "robocal ur plot")
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fmt = out_path.suffix.lstrip(".").lower() or "png"
    fig = plt.figure(figsize=(11, 5))
    supported = fig.canvas.get_supported_filetypes()
    if fmt not in supported:
        plt.close(fig)
        raise UsageError(
            f"--out {out_path}: unsupported figure format {fmt!r}; use one of {', '.join(sorted(supported))}"
        )
    far_m = float(np.max(np.linalg.norm(split_pts, axis=1)))
    panels = (
        (
            split_pts,
            f"split DH model (D/A segments)\nframes up to {far_m:.3g} m from the base",
            "tab:red",
            False,
        ),
        (corr_pts, "corrected model (ur_description)\nequal axis scales", "tab:blue", True),
    )
    for idx, (pts, label, color, equal) in enumerate(panels, start=1):
        ax = fig.add_subplot(1, 2, idx, projection="3d")
        ax.plot(pts[:, 0], pts[:, 1], pts[:, 2], "-o", color=color, markersize=3)
        ax.scatter([pts[0, 0]], [pts[0, 1]], [pts[0, 2]], color="tab:green", marker="s", s=40, label="base")
        ax.scatter([pts[-1, 0]], [pts[-1, 1]], [pts[-1, 2]], color="black", marker="*", s=60, label="flange")
        if equal:  # a cube around the arm, so the corrected links keep their real proportions
            centre = (pts.max(axis=0) + pts.min(axis=0)) / 2.0
            half = max(float(np.max(pts.max(axis=0) - pts.min(axis=0))) / 2.0, 1e-3)
            ax.set_xlim(centre[0] - half, centre[0] + half)
            ax.set_ylim(centre[1] - half, centre[1] + half)
            ax.set_zlim(centre[2] - half, centre[2] + half)
            ax.set_box_aspect((1.0, 1.0, 1.0))
        ax.set_title(label)
        ax.set_xlabel("x [m]")
        ax.set_ylabel("y [m]")
        ax.set_zlabel("z [m]")
        ax.legend(loc="upper left")
    if title:
        fig.suptitle(title)
    import io

    buf = io.BytesIO()
    fig.savefig(buf, format=fmt, dpi=100)
    plt.close(fig)
    return atomic_write_bytes(out_path, buf.getvalue())
