"""UR kinematics jobs: extract from a controller, correct offline, regenerate defaults, verify, plot.

Sources (controller via the primary interface, a DH YAML, or a model + calibration deltas) → core correction
→ ur_description kinematics YAML (+ optional in-place update of an expanded URDF) → verification through the
URDF forward kinematics (origin ``T(xyz)·Rz(y)Ry(p)Rx(r)``, then the joint's rotation).
"""

from __future__ import annotations

import itertools
import math
import os
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from ..backends import require
from ..core.dh import DHParameters, fk_dh
from ..core.se3 import homogeneous, rot_z, rotation_angle_between, transform_from_xyz_rpy_urdf
from ..core.ur import (
    JOINT_NAMES,
    UrKinematics,
    check_rpy_convention,
    correct_chain,
    correct_kinematics,
    default_kinematics,
    fk_origins,
    nominal_dh,
    six_transforms,
    split_chain,
)
from ..core.urhash import calib_hash
from ..errors import JointMismatchError, UsageError
from ..fileio import atomic_write_bytes, atomic_write_text, backup_paths, check_output_path, read_bytes
from ..formats.ur_kinematics import (
    kinematics_to_text,
    read_deltas,
    read_dh,
    read_kinematics,
    require_ur_joints,
    urdf_with_origins,
    write_kinematics,
)
from ..formats.urdf import UrdfDocument, UrdfJoint, UrdfModel, read_urdf

__all__ = [
    "DEFAULT_TOLERANCE_M",
    "DEFAULT_TOLERANCE_RAD",
    "MAX_VERIFY_SAMPLES",
    "CorrectionResult",
    "VerifyReport",
    "check_out_path",
    "correct",
    "defaults",
    "extract",
    "load_dh_input",
    "plot",
    "read_controller_dh",
    "urdf_fk",
    "verify",
    "verify_controller",
]

DEFAULT_TOLERANCE_M = 1e-9
"""verify: largest position error accepted without a warning (metres)."""
DEFAULT_TOLERANCE_RAD = 1e-9
"""verify: largest rotation error accepted without a warning (radians)."""
MAX_VERIFY_SAMPLES = 1_000_000
"""verify: most random joint vectors (bounds memory to a few hundred MB)."""

FloatArray = NDArray[np.float64]


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


@dataclass(frozen=True)
class VerifyReport:
    """FK comparison of a kinematics file (or URDF) with the DH model.

    Attributes:
        source: What was checked (file path and kind).
        samples: Number of random joint vectors (uniform in [−2π, 2π]).
        max_position_error_m: Largest ``‖p_file − p_dh‖`` over the samples, metres.
        max_rotation_error_rad: Largest relative rotation angle, radians.
        file_hash: The file's ``hash`` (None for a URDF).
        dh_hash: ``calib_`` hash of the DH.
        warnings: Tolerance or hash problems.
    """

    source: str
    samples: int
    max_position_error_m: float
    max_rotation_error_rad: float
    file_hash: str | None
    dh_hash: str
    warnings: tuple[str, ...] = ()


def check_out_path(path: str | os.PathLike[str], what: str = "--out") -> Path:
    """Refuse an output path whose folder does not exist or that is a directory (exit 2, nothing written)."""
    return check_output_path(path, what)


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
        check_out_path(urdf_out, "--urdf-out")
        if Path(urdf_out).resolve() == Path(out).resolve():
            raise UsageError(f"--urdf-out {urdf_out} is the same file as --out; give the URDF its own path")
        doc = UrdfDocument.load(urdf_in)  # parse + validate before anything is written
        require_ur_joints(doc.model(), urdf_in)


def _check_connection(host: str, port: int, timeout_s: float) -> None:
    from ..backends.ur_primary import check_connection_args

    check_connection_args(host, port, timeout_s)


def _check_samples(samples: int, flag: str, most: int) -> None:
    if samples < 1:
        raise UsageError(f"{flag} {samples}: expected at least 1")
    if samples > most:
        raise UsageError(f"{flag} {samples}: expected at most {most}")


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
    from ..backends.ur_primary import PrimaryClient

    with PrimaryClient(host, port, timeout_s) as client:
        info = client.read_kinematics()
        warnings = tuple(client.warnings)
    return correct(info.dh, out, rpy=rpy, urdf_in=urdf_in, urdf_out=urdf_out, warnings=warnings)


def defaults(model: str, out: str | os.PathLike[str], *, rpy: str = "upstream") -> CorrectionResult:
    """Regenerate ur_description's ``default_kinematics.yaml`` for ``model`` (URSim nominal DH)."""
    rpy = check_rpy_convention(rpy)
    out_path = check_out_path(out)
    kin = default_kinematics(model, rpy)
    return CorrectionResult(nominal_dh(model), kin, write_kinematics(out_path, kin))


def _rotation_about(axis: tuple[float, float, float], q_rad: FloatArray) -> FloatArray:
    """``(N, 3, 3)`` rotations by ``q_rad`` about a unit ``axis`` (Rodrigues)."""
    k = np.asarray(axis, dtype=np.float64)
    n = float(np.linalg.norm(k))
    if n == 0.0:
        raise UsageError("URDF joint axis is the zero vector")
    k = k / n
    if k[0] == 0.0 and k[1] == 0.0 and k[2] > 0:
        return rot_z(q_rad)
    K = np.array([[0.0, -k[2], k[1]], [k[2], 0.0, -k[0]], [-k[1], k[0], 0.0]])
    s = np.sin(q_rad)[:, None, None]
    c = np.cos(q_rad)[:, None, None]
    return np.asarray(np.eye(3) + s * K + (1.0 - c) * (K @ K), dtype=np.float64)


FLANGE_LINK = "tool0"
"""ur_description's flange frame (wrist_3_link → flange → tool0, fixed joints composing to identity)."""

_REVOLUTE = ("revolute", "continuous")


def _ur_chain(model: UrdfModel, source: str | os.PathLike[str]) -> tuple[list[UrdfJoint], list[UrdfJoint]]:
    """The six UR joints in series and the fixed joints from ``wrist_3_joint``'s child down to ``tool0``.

    Raises:
        JointMismatchError: A UR joint is missing, not revolute, or not attached to the previous one's child;
            or a joint between wrist_3's link and ``tool0`` moves.
    """
    require_ur_joints(model, source)
    arm = [model.joint(name) for name in JOINT_NAMES]
    for prev, j in itertools.pairwise(arm):
        if j.parent != prev.child:
            raise JointMismatchError(
                f"URDF {source}: {j.name}'s parent is {j.parent}; expected {prev.child} (child of {prev.name})"
            )
    for j in arm:
        if j.type not in _REVOLUTE:
            raise JointMismatchError(f"URDF {source}: {j.name} is {j.type}; expected revolute")
    by_child = {j.child: j for j in model.joints}
    tail: list[UrdfJoint] = []
    link = FLANGE_LINK
    while link != arm[-1].child and link in by_child and len(tail) <= len(by_child):  # walk up from tool0
        tail.append(by_child[link])
        link = by_child[link].parent
    if link != arm[-1].child:
        return arm, []  # no tool0 below wrist_3: end at wrist_3's link (the same frame in ur_description)
    tail.reverse()
    for j in tail:
        if j.type != "fixed":
            raise JointMismatchError(
                f"URDF {source}: joint {j.name} between {arm[-1].child} and {FLANGE_LINK} is {j.type}; "
                "expected fixed"
            )
    return arm, tail


def urdf_fk(urdf_path: str | os.PathLike[str], q_rad: FloatArray) -> FloatArray:
    """FK of an expanded URDF the way ur_description builds it, from ``base_link_inertia`` to ``tool0``.

    ``Π origin_k · Rot(axis_k, q_k)`` over the six UR joints, then the fixed joints down to ``tool0``
    (wrist_3_link → flange → tool0).

    Args:
        urdf_path: Expanded URDF with ``shoulder_pan_joint`` … ``wrist_3_joint`` in series.
        q_rad: ``(N, 6)`` joint positions.

    Returns:
        ``(N, 4, 4)`` transforms from ``shoulder_pan_joint``'s parent frame (``base_link_inertia``) to ``tool0``
        (to ``wrist_3_joint``'s child when the URDF has no ``tool0`` below it).

    Raises:
        JointMismatchError: Missing, disconnected or non-revolute UR joints, or a moving joint before tool0.
    """
    model = read_urdf(urdf_path)
    arm, tail = _ur_chain(model, urdf_path)
    n = q_rad.shape[0]
    T = np.broadcast_to(np.eye(4), (n, 4, 4)).copy()
    for k, j in enumerate(arm):
        origin = transform_from_xyz_rpy_urdf(np.array(j.origin_xyz), np.array(j.origin_rpy))
        Rq = homogeneous(_rotation_about(j.axis, q_rad[:, k]), np.zeros(3))
        T = T @ origin @ Rq
    for j in tail:
        T = T @ transform_from_xyz_rpy_urdf(np.array(j.origin_xyz), np.array(j.origin_rpy))
    return np.asarray(T, dtype=np.float64)


def _report(
    source: str,
    T_file: FloatArray,
    T_dh: FloatArray,
    file_hash: str | None,
    dh: DHParameters,
    tol: tuple[float, float],
) -> VerifyReport:
    pos = float(np.max(np.linalg.norm(T_file[:, :3, 3] - T_dh[:, :3, 3], axis=1)))
    rot = float(np.max(rotation_angle_between(T_file[:, :3, :3], T_dh[:, :3, :3])))
    dh_hash = calib_hash(dh.theta_rad, dh.d_m, dh.a_m, dh.alpha_rad)
    warnings: list[str] = []
    if not (pos <= tol[0]) or not (rot <= tol[1]):
        warnings.append(
            f"{source}: FK differs from the DH model by up to {pos:.3g} m / {rot:.3g} rad "
            f"(tolerance {tol[0]:g} m / {tol[1]:g} rad)"
        )
    if file_hash is not None and file_hash != dh_hash:
        warnings.append(
            f"{source}: hash {file_hash} does not match the DH ({dh_hash}); the driver will complain"
        )
    return VerifyReport(source, int(T_dh.shape[0]), pos, rot, file_hash, dh_hash, tuple(warnings))


def verify(
    kinematics_path: str | os.PathLike[str] | None,
    dh: DHParameters,
    *,
    urdf_path: str | os.PathLike[str] | None = None,
    samples: int = 1000,
    seed: int = 0,
    tolerance_m: float = DEFAULT_TOLERANCE_M,
    tolerance_rad: float = DEFAULT_TOLERANCE_RAD,
    q_rad: FloatArray | None = None,
) -> list[VerifyReport]:
    """Compare the FK of a kinematics YAML (as ur_description builds it) and/or a URDF with the DH FK.

    Args:
        kinematics_path: ur_description kinematics YAML (may be None when only ``urdf_path`` is checked).
        dh: Raw controller DH.
        urdf_path: Optional expanded URDF.
        samples: Random joint vectors, uniform in [−2π, 2π] (fixed ``seed``).
        seed: RNG seed.
        tolerance_m: Position tolerance for the warning.
        tolerance_rad: Rotation tolerance for the warning.
        q_rad: ``(N, 6)`` joint vectors (rad) to compare at instead of the random ones (``--q``).

    Returns:
        One report per checked source.
    """
    if kinematics_path is None and urdf_path is None:
        raise UsageError("nothing to verify: give a kinematics FILE and/or --urdf")
    if q_rad is not None:
        q = np.asarray(q_rad, dtype=np.float64)
        if q.ndim != 2 or q.shape[1] != 6 or q.shape[0] == 0 or not np.all(np.isfinite(q)):
            raise UsageError(f"--q: expected six finite joint positions per vector, got shape {q.shape}")
    else:
        _check_samples(samples, "--samples", MAX_VERIFY_SAMPLES)
        rng = np.random.default_rng(seed)
        q = rng.uniform(-2.0 * math.pi, 2.0 * math.pi, size=(samples, 6))
    T_dh = fk_dh(dh, q)
    tol = (tolerance_m, tolerance_rad)
    reports: list[VerifyReport] = []
    if kinematics_path is not None:
        kin = read_kinematics(kinematics_path)
        T = fk_origins(kin.xyz_array(), kin.rpy_array(), q)
        reports.append(_report(f"kinematics YAML {kinematics_path}", T, T_dh, kin.hash, dh, tol))
    if urdf_path is not None:
        reports.append(_report(f"URDF {urdf_path}", urdf_fk(urdf_path, q), T_dh, None, dh, tol))
    return reports


def read_controller_dh(host: str, *, port: int = 30001, timeout_s: float = 10.0) -> tuple[DHParameters, list[str]]:
    """The calibrated DH a controller reports (KinematicsInfo), with the reader's warnings (status ≠ 2).

    Raises:
        UsageError: Bad host/port/timeout.
        CalibTimeoutError, ProtocolError, DeviceError: As :class:`~robocal.backends.ur_primary.PrimaryClient`.
    """
    _check_connection(host, port, timeout_s)
    from ..backends.ur_primary import PrimaryClient

    with PrimaryClient(host, port, timeout_s) as client:
        info = client.read_kinematics()
        return info.dh, list(client.warnings)


def verify_controller(
    kinematics_path: str | os.PathLike[str],
    host: str,
    *,
    port: int = 30001,
    timeout_s: float = 10.0,
    samples: int = 20,
    tolerance_m: float = 1e-6,
    tolerance_rad: float = 1e-6,
) -> VerifyReport:
    """Compare the YAML's FK with the controller's own base → TCP pose (CartesianInfo) for live joint states.

    The TCP offset must be zero (then TCP = flange = ``tool0``); a non-zero offset is refused. The controller
    streams about 10 states per second, so ``samples`` states take ``samples / 10`` s. The default tolerance
    (1 µm / 1 µrad) allows for the controller's own rounding.

    Args:
        kinematics_path: ur_description kinematics YAML.
        host: Controller address.
        port: Primary interface port.
        timeout_s: Deadline for connecting and the KinematicsInfo, and again for each pose sample (per read).
        samples: Number of RobotState samples to compare.
        tolerance_m: Position tolerance for the warning.
        tolerance_rad: Rotation tolerance for the warning.

    Returns:
        One report (its ``dh_hash`` is the live controller's hash).
    """
    _check_connection(host, port, timeout_s)
    _check_samples(samples, "--controller-samples", 10_000)
    kin = read_kinematics(kinematics_path)
    from ..backends.ur_primary import PrimaryClient
    from ..core.se3 import matrix_from_rotvec

    with PrimaryClient(host, port, timeout_s) as client:
        info = client.read_kinematics()
        got = client.read_pose_samples(samples)
        warnings = list(client.warnings)
    if any(any(v != 0.0 for v in s.tcp_offset) for s in got):
        raise UsageError(
            f"UR controller {host}:{port}: the active TCP offset is not zero; set an empty TCP to verify the flange"
        )
    q = np.array([s.q_rad for s in got])
    T_ctrl = homogeneous(
        matrix_from_rotvec(np.array([s.tcp_rotvec_rad for s in got])), np.array([s.tcp_xyz_m for s in got])
    )
    T_file = fk_origins(kin.xyz_array(), kin.rpy_array(), q)
    report = _report(
        f"controller {host}:{port} vs {kinematics_path}",
        T_file,
        T_ctrl,
        kin.hash,
        info.dh,
        (tolerance_m, tolerance_rad),
    )
    return replace(report, warnings=tuple(warnings) + report.warnings)


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
