"""UR verification: the kinematics YAML, a URDF or the controller's own pose against the DH model.

The DH forward kinematics (:func:`robocal.core.dh.fk_dh`) is compared with the URDF-chain forward kinematics
(:func:`robocal.core.chain.fk_chain`): a kinematics YAML is evaluated as ur_description builds the URDF
(:func:`robocal.core.ur.fk_origins`), an expanded URDF through :func:`robocal.formats.urdf_chain.chain_from_urdf`
from ``shoulder_pan_joint``'s parent down to ``tool0``. Neither side uses the other's model.
"""

from __future__ import annotations

import itertools
import math
import os
from dataclasses import dataclass, replace

import numpy as np

from ...backends import load_backend
from ...backends.ur_primary import PoseSample
from ...core.arrays import FloatArray
from ...core.chain import ChainJoint, fk_chain
from ...core.dh import DHParameters, fk_dh
from ...core.se3 import homogeneous, rotation_angle_between
from ...core.ur import JOINT_NAMES, fk_origins
from ...core.urhash import calib_hash
from ...errors import JointMismatchError, UsageError
from ...formats.ur_kinematics import read_kinematics, require_ur_joints
from ...formats.urdf import UrdfModel, read_urdf
from ...formats.urdf_chain import chain_from_urdf

__all__ = [
    "DEFAULT_TOLERANCE_M",
    "DEFAULT_TOLERANCE_RAD",
    "FLANGE_LINK",
    "MAX_VERIFY_SAMPLES",
    "RtdeVerifyRequest",
    "VerifyReport",
    "urdf_fk",
    "verify",
    "verify_controller",
    "verify_rtde",
]

DEFAULT_TOLERANCE_M = 1e-9
"""verify: largest position error accepted without a warning (metres)."""
DEFAULT_TOLERANCE_RAD = 1e-9
"""verify: largest rotation error accepted without a warning (radians)."""
MAX_VERIFY_SAMPLES = 1_000_000
"""verify: most random joint vectors (bounds memory to a few hundred MB)."""

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


FLANGE_LINK = "tool0"
"""ur_description's flange frame (wrist_3_link → flange → tool0, fixed joints composing to identity)."""

_REVOLUTE = ("revolute", "continuous")


def _ur_chain(model: UrdfModel, source: str | os.PathLike[str]) -> tuple[list[ChainJoint], list[ChainJoint]]:
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
    tail: list[ChainJoint] = []
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
    (wrist_3_link → flange → tool0), by :func:`robocal.core.chain.fk_chain`.

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
    chain = chain_from_urdf(model, arm[0].parent, (tail or arm)[-1].child)
    return fk_chain(chain, np.asarray(q_rad, dtype=np.float64).reshape(-1, len(arm)))


def _check_samples(samples: int, flag: str, most: int) -> None:
    if samples < 1:
        raise UsageError(f"{flag} {samples}: expected at least 1")
    if samples > most:
        raise UsageError(f"{flag} {samples}: expected at most {most}")


def _report(
    source: str,
    T_base_tool0_file: FloatArray,
    T_base_tool0_ref: FloatArray,
    file_hash: str | None,
    dh: DHParameters,
    tol: tuple[float, float],
) -> VerifyReport:
    """Compare a file's ``(N, 4, 4)`` base → tool0 poses with the reference's (the DH model or the controller)."""
    pos = float(np.max(np.linalg.norm(T_base_tool0_file[:, :3, 3] - T_base_tool0_ref[:, :3, 3], axis=1)))
    rot = float(np.max(rotation_angle_between(T_base_tool0_file[:, :3, :3], T_base_tool0_ref[:, :3, :3])))
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
    return VerifyReport(source, int(T_base_tool0_ref.shape[0]), pos, rot, file_hash, dh_hash, tuple(warnings))


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
    T_base_tool0_dh = fk_dh(dh, q)
    tol = (tolerance_m, tolerance_rad)
    reports: list[VerifyReport] = []
    if kinematics_path is not None:
        kin = read_kinematics(kinematics_path)
        T_base_tool0 = fk_origins(kin.xyz_array(), kin.rpy_array(), q)
        reports.append(_report(f"kinematics YAML {kinematics_path}", T_base_tool0, T_base_tool0_dh, kin.hash, dh, tol))
    if urdf_path is not None:
        reports.append(_report(f"URDF {urdf_path}", urdf_fk(urdf_path, q), T_base_tool0_dh, None, dh, tol))
    return reports


def _controller_poses(got: list[PoseSample], where: str) -> tuple[FloatArray, FloatArray]:
    """``(N, 6)`` joint positions and ``(N, 4, 4)`` base → TCP poses of controller samples (TCP offset zero).

    Raises:
        UsageError: The active TCP offset is not zero (then the TCP is not the flange, ``tool0``).
    """
    from ...core.se3 import matrix_from_rotvec

    if any(any(v != 0.0 for v in s.tcp_offset) for s in got):
        raise UsageError(
            f"UR controller {where}: the active TCP offset is not zero; set an empty TCP to verify the flange"
        )
    q = np.array([s.q_rad for s in got], dtype=np.float64)
    T = homogeneous(
        matrix_from_rotvec(np.array([s.tcp_rotvec_rad for s in got])), np.array([s.tcp_xyz_m for s in got])
    )
    return q, T


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
    from ...backends.ur_primary import check_connection_args

    check_connection_args(host, port, timeout_s)
    _check_samples(samples, "--controller-samples", 10_000)
    kin = read_kinematics(kinematics_path)
    with load_backend("ur_primary")(host, port, timeout_s) as client:
        info = client.read_kinematics()
        got = client.read_pose_samples(samples)
        warnings = list(client.warnings)
    q, T_base_tool0_ctrl = _controller_poses(got, f"{host}:{port}")
    report = _report(
        f"controller {host}:{port} vs {kinematics_path}",
        fk_origins(kin.xyz_array(), kin.rpy_array(), q),
        T_base_tool0_ctrl,
        kin.hash,
        info.dh,
        (tolerance_m, tolerance_rad),
    )
    return replace(report, warnings=tuple(warnings) + report.warnings)


@dataclass(frozen=True)
class RtdeVerifyRequest:
    """What ``ur verify --rtde`` compares with the controller's ``actual_TCP_pose``; checked when built.

    Attributes:
        host: Controller address.
        port: RTDE port.
        kinematics_path: ur_description kinematics YAML (its hash is checked against ``dh`` when both are given).
        dh: A DH model (``--dh``/``--model``/``--deltas``) whose FK is compared too.
        urdf_path: An expanded URDF whose FK is compared too.
        timeout_s: Deadline for connecting and the setup, and again for each data package.
        samples: Number of data packages to compare.
        tolerance_m: Position tolerance for the warning.
        tolerance_rad: Rotation tolerance for the warning.

    Raises:
        UsageError: Nothing to compare, bad connection arguments or sample count (exit 2).
    """

    host: str
    port: int = 30004
    kinematics_path: str | os.PathLike[str] | None = None
    dh: DHParameters | None = None
    urdf_path: str | os.PathLike[str] | None = None
    timeout_s: float = 10.0
    samples: int = 20
    tolerance_m: float = 1e-6
    tolerance_rad: float = 1e-6

    def __post_init__(self) -> None:
        from ...backends.ur_primary import check_connection_args

        if self.kinematics_path is None and self.urdf_path is None and self.dh is None:
            raise UsageError("--rtde needs a kinematics FILE, --urdf or a DH (--dh/--model) to compare")
        check_connection_args(self.host, self.port, self.timeout_s)
        _check_samples(self.samples, "--controller-samples", 10_000)


def verify_rtde(request: RtdeVerifyRequest) -> list[VerifyReport]:
    """Compare the FK of a kinematics YAML, a URDF and/or a DH with the controller's ``actual_TCP_pose`` (RTDE).

    Each data package carries ``actual_q`` and ``actual_TCP_pose`` of the same controller cycle, so the arm
    may move while the samples are read. The TCP offset (``tcp_offset``) must be zero (TCP = flange =
    ``tool0``). The default tolerance (1 µm / 1 µrad) allows for the controller's own rounding.

    Args:
        request: What to compare, where the controller is (checked when it was built).

    Returns:
        One report per source, in the order YAML, URDF, DH.

    Raises:
        UsageError: A non-zero TCP offset (exit 2).
        DeviceError: The controller cannot be reached or stops answering (exit 3).
    """
    r = request
    host, port, kinematics_path, dh, urdf_path = r.host, r.port, r.kinematics_path, r.dh, r.urdf_path
    timeout_s, samples, tolerance_m, tolerance_rad = r.timeout_s, r.samples, r.tolerance_m, r.tolerance_rad
    kin = read_kinematics(kinematics_path) if kinematics_path is not None else None
    with load_backend("ur_rtde")(host, port, timeout_s) as client:
        got = client.read_pose_samples(samples)
    where = f"{host}:{port}"
    q, T_base_tool0_ctrl = _controller_poses(got, f"{where} (RTDE)")
    tol = (tolerance_m, tolerance_rad)
    reports: list[VerifyReport] = []

    def add(source: str, T_base_tool0: FloatArray, file_hash: str | None) -> None:
        zeros = (0.0,) * 6
        report = _report(
            f"RTDE {where} vs {source}",
            T_base_tool0,
            T_base_tool0_ctrl,
            file_hash if dh is not None else None,
            dh or DHParameters(zeros, zeros, zeros, zeros),
            tol,
        )
        if dh is None:  # no DH given: no hash to check the file's against
            report = replace(report, dh_hash="")
        reports.append(report)

    if kin is not None:
        add(str(kinematics_path), fk_origins(kin.xyz_array(), kin.rpy_array(), q), kin.hash)
    if urdf_path is not None:
        add(str(urdf_path), urdf_fk(urdf_path, q), None)
    if dh is not None:
        add("DH", fk_dh(dh, q), None)
    return reports
