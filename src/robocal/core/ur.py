"""Universal Robots calibration correction (pure numpy / math, no I/O).

The controller reports calibrated DH parameters in which joints 2 and 3 can have ``d`` of hundreds of
metres (the upper-arm length is then carried by ``d2·tan α2``). :func:`correct_chain` moves the ``d`` of
joints 2 and 3 onto the next joint along that joint's axis (the ``ur_calibration`` algorithm), so that
the six per-joint transforms describe the physical arm while ``T_base_flange`` stays the DH FK.

The chain has 12 matrices: joint ``i`` gives ``D_i = [Rz(θ_i) | (0, 0, d_i)]`` and
``A_i = [Rx(α_i) | (a_i, 0, 0)]``. ``correctAxis(i)`` (joint 2, then joint 3) intersects the next
joint's axis with the XY plane of the frame before ``D_i`` at ``I``; then ``D_i ← Rz(θ')`` with
``θ' = atan2(I_y, I_x) − π``, ``A_i ← [Rz(θ_i − θ')·Rx(α_i) | (−‖I‖, 0, 0)]``, and the next joint's
``d`` absorbs the move along its axis.

Arithmetic follows upstream operation by operation (Eigen's ``AngleAxis`` matrices, sequential 4×4 products,
``ParametrizedLine``/``Hyperplane`` intersection) so that ordinary inputs give the same numbers as
``ur_calibration``. Where upstream breaks, robocal differs on purpose:

* next joint's ``d`` exactly 0: upstream normalises a zero vector (NaN); robocal uses the axis direction.
* ``a_i`` exactly 0: upstream omits ``− π`` and puts the link end at ``−I``; robocal always subtracts π.
* ``cos α_i < 0``: upstream corrects ``d`` with the wrong sign; robocal uses the signed axis direction.
* ``|cos α_i|`` below :data:`MIN_ABS_COS_ALPHA` (axis parallel to the plane, ``α ≈ ±π/2``): refused with
  :class:`~robocal.errors.InvalidCalibrationError` (upstream writes ±4.5e15 m and NaN).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..errors import InvalidCalibrationError, ShapeMismatchError, UsageError
from .dh import DHParameters
from .se3 import eigen_euler_xyz, rot_z, rpy_urdf_from_matrix, transform_from_xyz_rpy_urdf
from .urhash import calib_hash

__all__ = [
    "JOINT_NAMES",
    "LINK_NAMES",
    "MIN_ABS_COS_ALPHA",
    "RPY_CONVENTIONS",
    "TEST_SET_3_DELTAS",
    "URSIM_HALF_PI",
    "UR_MODELS",
    "LinkOrigin",
    "NominalDeviation",
    "UrKinematics",
    "check_rpy_convention",
    "correct_chain",
    "correct_kinematics",
    "default_kinematics",
    "deviation_from_nominal",
    "fk_origins",
    "nominal_dh",
    "six_transforms",
    "split_chain",
]

FloatArray = NDArray[np.float64]
Mat = list[list[float]]

LINK_NAMES: tuple[str, ...] = ("shoulder", "upper_arm", "forearm", "wrist_1", "wrist_2", "wrist_3")
"""Keys under ``kinematics`` in ur_description's YAML, in file order."""

JOINT_NAMES: tuple[str, ...] = (
    "shoulder_pan_joint",
    "shoulder_lift_joint",
    "elbow_joint",
    "wrist_1_joint",
    "wrist_2_joint",
    "wrist_3_joint",
)
"""URDF joints whose ``<origin>`` the six YAML entries become (same order as :data:`LINK_NAMES`)."""

RPY_CONVENTIONS: tuple[str, ...] = ("urdf", "upstream")
"""``urdf``: correct URDF fixed-axis rpy. ``upstream``: Eigen ``eulerAngles(0, 1, 2)`` as upstream writes."""

URSIM_HALF_PI = 1.570796327
"""What URSim reports as π/2; the default kinematics files are generated with it."""

MIN_ABS_COS_ALPHA = 1e-3
"""Smallest ``|cos α|`` of joints 2 and 3 the correction accepts (α within 0.057° of ±π/2 is refused)."""

UR_MODELS: dict[str, tuple[float, float, float, float, float, float]] = {
    # model: (a2, a3, d1, d4, d5, d6) in metres, from ur_description's default_kinematics.yaml files
    "ur3": (-0.24365, -0.21325, 0.1519, 0.11235, 0.08535, 0.0819),
    "ur5": (-0.425, -0.39225, 0.089159, 0.10915, 0.09465, 0.0823),
    "ur10": (-0.612, -0.5723, 0.1273, 0.163941, 0.1157, 0.0922),
    "ur3e": (-0.24355, -0.2132, 0.15185, 0.13105, 0.08535, 0.0921),
    "ur5e": (-0.425, -0.3922, 0.1625, 0.1333, 0.0997, 0.0996),
    "ur10e": (-0.6127, -0.57155, 0.1807, 0.17415, 0.11985, 0.11655),
    "ur16e": (-0.4784, -0.36, 0.1807, 0.17415, 0.11985, 0.11655),
    "ur20": (-0.862, -0.7287, 0.2363, 0.201, 0.1593, 0.1543),
    "ur30": (-0.637, -0.5037, 0.2363, 0.201, 0.1593, 0.1543),
}
"""Nominal DH lengths per model; θ = 0, α = (π/2, 0, 0, π/2, −π/2, 0), a1 = a4 = a5 = a6 = 0, d2 = d3 = 0."""


def nominal_dh(model: str, *, half_pi: float = URSIM_HALF_PI) -> DHParameters:
    """Nominal DH parameters of a UR model.

    Args:
        model: One of :data:`UR_MODELS` (``ur3`` … ``ur30``), case-insensitive.
        half_pi: Value used for α = ±π/2. The default is URSim's ``1.570796327`` (what the controller reports
            and what the default files are generated from); pass ``math.pi / 2`` for the ideal model.

    Returns:
        The six-joint DH model.

    Raises:
        UsageError: Unknown model (the message lists the valid ones).
    """
    key = model.strip().lower()
    if key not in UR_MODELS:
        raise UsageError(f"unknown UR model {model!r}; valid: {', '.join(UR_MODELS)}")
    a2, a3, d1, d4, d5, d6 = UR_MODELS[key]
    return DHParameters(
        theta_rad=(0.0, 0.0, 0.0, 0.0, 0.0, 0.0),
        a_m=(0.0, a2, a3, 0.0, 0.0, 0.0),
        d_m=(d1, 0.0, 0.0, d4, d5, d6),
        alpha_rad=(half_pi, 0.0, 0.0, half_pi, -half_pi, 0.0),
    )


# --- Eigen-faithful scalar helpers -------------------------------------------------------------------------


def _identity4() -> Mat:
    return [[1.0 if r == c else 0.0 for c in range(4)] for r in range(4)]


def _angle_axis(angle: float, axis: tuple[float, float, float]) -> Mat:
    """3×3 rotation exactly as Eigen's ``AngleAxisd(angle, axis).toRotationMatrix()`` computes it."""
    s, c = math.sin(angle), math.cos(angle)
    sa = (s * axis[0], s * axis[1], s * axis[2])
    c1 = ((1.0 - c) * axis[0], (1.0 - c) * axis[1], (1.0 - c) * axis[2])
    R = [[0.0] * 3 for _ in range(3)]
    tmp = c1[0] * axis[1]
    R[0][1] = tmp - sa[2]
    R[1][0] = tmp + sa[2]
    tmp = c1[0] * axis[2]
    R[0][2] = tmp + sa[1]
    R[2][0] = tmp - sa[1]
    tmp = c1[1] * axis[2]
    R[1][2] = tmp - sa[0]
    R[2][1] = tmp + sa[0]
    for k in range(3):
        R[k][k] = c1[k] * axis[k] + c
    return R


_UNIT_X = (1.0, 0.0, 0.0)
_UNIT_Z = (0.0, 0.0, 1.0)


def _mm(A: Mat, B: Mat) -> Mat:
    n, m, p = len(A), len(B), len(B[0])
    out = [[0.0] * p for _ in range(n)]
    for r in range(n):
        for c in range(p):
            acc = A[r][0] * B[0][c]
            for k in range(1, m):
                acc = A[r][k] * B[k][c] + acc
            out[r][c] = acc
    return out


def _with_rotation(T: Mat, R: Mat) -> Mat:
    out = [row[:] for row in T]
    for r in range(3):
        for c in range(3):
            out[r][c] = R[r][c]
    return out


def _dot3(u: Sequence[float], v: Sequence[float]) -> float:
    return (u[0] * v[0] + u[1] * v[1]) + u[2] * v[2]


def _build_chain(dh: DHParameters) -> list[Mat]:
    chain: list[Mat] = []
    for i in range(dh.n_joints):
        D = _with_rotation(_identity4(), _angle_axis(dh.theta_rad[i], _UNIT_Z))
        D[2][3] = dh.d_m[i]
        A = _with_rotation(_identity4(), _angle_axis(dh.alpha_rad[i], _UNIT_X))
        A[0][3] = dh.a_m[i]
        chain += [D, A]
    return chain


def _correct_axis(chain: list[Mat], dh: DHParameters, i: int) -> None:
    """Correct joint ``i`` (0-based: 1 = joint 2) in place; see the module docstring."""
    d_i = chain[2 * i][2][3]
    if d_i == 0.0:
        return  # nothing to move; ideal and URSim models pass through bit-identical
    cos_alpha = math.cos(dh.alpha_rad[i])
    if abs(cos_alpha) < MIN_ABS_COS_ALPHA:
        raise InvalidCalibrationError(
            f"DH joint {i + 1}: alpha = {dh.alpha_rad[i]!r} rad puts joint {i + 2}'s axis (nearly) parallel "
            f"to joint {i + 1}'s XY plane (|cos alpha| < {MIN_ABS_COS_ALPHA}); d{i + 1} = {d_i!r} m "
            "cannot be moved onto the next axis"
        )
    M = _mm(_identity4(), _mm(chain[2 * i], chain[2 * i + 1]))
    p = [M[0][3], M[1][3], M[2][3]]
    E = _mm(M, chain[2 * i + 2])
    e = [E[0][3], E[1][3], E[2][3]]
    diff = [e[0] - p[0], e[1] - p[1], e[2] - p[2]]
    sq = _dot3(diff, diff)
    if 0.0 < sq < math.inf:
        nrm = math.sqrt(sq)
        direction = [diff[0] / nrm, diff[1] / nrm, diff[2] / nrm]
        sigma = 1.0 if chain[2 * i + 2][2][3] > 0.0 else -1.0  # direction = sigma * next joint's z axis
    else:  # next joint's d is 0 (or its square under/overflows): take its axis (z after A_i) directly
        direction = [M[0][2], M[1][2], M[2][2]]
        sigma = 1.0
    normal = (0.0, 0.0, 1.0)
    offset = -0.0  # Hyperplane(normal, point = 0): -normal.dot(0)
    dir_z = _dot3(normal, direction)
    if dir_z == 0.0 or not math.isfinite(dir_z):
        raise InvalidCalibrationError(
            f"DH joint {i + 1}: joint {i + 2}'s axis does not cross joint {i + 1}'s XY plane "
            f"(d{i + 2} = {chain[2 * i + 2][2][3]!r} m)"
        )
    t = -(offset + _dot3(normal, p)) / dir_z
    inter = [p[0] + direction[0] * t, p[1] + direction[1] * t, p[2] + direction[2] * t]
    new_theta = math.atan2(inter[1], inter[0]) - math.pi
    new_length = -1.0 * math.sqrt(_dot3(inter, inter))
    distance_correction = t * sigma
    if not all(math.isfinite(v) for v in (t, new_theta, new_length)):
        raise InvalidCalibrationError(f"DH joint {i + 1}: the correction is not finite (d = {d_i!r} m)")
    D = _with_rotation(chain[2 * i], _angle_axis(new_theta, _UNIT_Z))
    D[2][3] = 0.0
    A = _with_rotation(
        chain[2 * i + 1],
        _mm(_angle_axis(dh.theta_rad[i] - new_theta, _UNIT_Z), _angle_axis(dh.alpha_rad[i], _UNIT_X)),
    )
    A[0][3] = new_length
    chain[2 * i] = D
    chain[2 * i + 1] = A
    chain[2 * i + 2][2][3] -= distance_correction


def correct_chain(dh: DHParameters) -> FloatArray:
    """Build the 12-matrix split chain and correct joints 2 and 3.

    Args:
        dh: Raw controller DH (six joints).

    Returns:
        ``(12, 4, 4)`` chain ``D_1, A_1, …, D_6, A_6`` after correction; ``Π (S_k · Rz(q_k))`` over
        :func:`six_transforms` equals the DH forward kinematics.

    Raises:
        ShapeMismatchError: Not six joints.
        InvalidCalibrationError: A degenerate input that cannot be corrected (see the module docstring).
    """
    if dh.n_joints != 6:
        raise ShapeMismatchError(f"UR DH parameters: expected 6 joints, got {dh.n_joints}")
    chain = _build_chain(dh)
    _correct_axis(chain, dh, 1)
    _correct_axis(chain, dh, 2)
    arr = np.array(chain, dtype=np.float64)
    if not np.all(np.isfinite(arr)):
        raise InvalidCalibrationError("UR correction produced a non-finite value; check the DH input")
    return arr


def six_transforms(chain: ArrayLike) -> FloatArray:
    """The six joint-origin transforms ``S_0 = D_1``, ``S_k = A_k · D_{k+1}`` (the 7th, ``A_6``, is dropped).

    Args:
        chain: ``(12, 4, 4)`` chain from :func:`correct_chain`.

    Returns:
        ``(6, 4, 4)`` transforms, parent joint frame → child joint frame (before the joint's ``Rz(q)``).
    """
    c = np.asarray(chain, dtype=np.float64)
    if c.shape != (12, 4, 4):
        raise ShapeMismatchError(f"UR chain: expected (12, 4, 4), got {c.shape}")
    mats: list[Mat] = [c[0].tolist()]
    for k in range(1, 11, 2):
        mats.append(_mm(c[k].tolist(), c[k + 1].tolist()))
    return np.array(mats, dtype=np.float64)


@dataclass(frozen=True)
class LinkOrigin:
    """One entry of the kinematics YAML: a URDF joint origin.

    Attributes:
        name: YAML key (``shoulder`` … ``wrist_3``).
        xyz_m: Translation parent → child in metres.
        rpy_rad: (roll, pitch, yaw) in radians, in the convention of :attr:`UrKinematics.rpy_convention`.
    """

    name: str
    xyz_m: tuple[float, float, float]
    rpy_rad: tuple[float, float, float]


@dataclass(frozen=True)
class UrKinematics:
    """The content of a ur_description kinematics file.

    Attributes:
        links: Six :class:`LinkOrigin` in :data:`LINK_NAMES` order.
        hash: ``calib_<uint64>`` of the raw DH (what the driver compares with the robot).
        rpy_convention: ``"urdf"`` (correct) or ``"upstream"`` (Eigen eulerAngles, as ur_calibration writes).
    """

    links: tuple[LinkOrigin, ...]
    hash: str
    rpy_convention: str = "urdf"

    def xyz_array(self) -> FloatArray:
        """``(6, 3)`` translations in metres."""
        return np.array([lk.xyz_m for lk in self.links], dtype=np.float64)

    def rpy_array(self) -> FloatArray:
        """``(6, 3)`` rpy angles in radians."""
        return np.array([lk.rpy_rad for lk in self.links], dtype=np.float64)


def check_rpy_convention(rpy: str) -> str:
    """Normalise an rpy convention name (any case, surrounding spaces ignored, like ``--model``).

    Returns:
        ``"urdf"`` or ``"upstream"``.

    Raises:
        UsageError: Not one of :data:`RPY_CONVENTIONS`; names ``--rpy``.
    """
    key = rpy.strip().lower()
    if key not in RPY_CONVENTIONS:
        raise UsageError(f"--rpy {rpy!r}: expected one of {', '.join(RPY_CONVENTIONS)} (any case)")
    return key


def _clean(v: float) -> float:
    return float(v) + 0.0  # -0.0 → 0.0


def origins_from_transforms(transforms: ArrayLike, rpy: str = "urdf") -> tuple[LinkOrigin, ...]:
    """Six transforms → six :class:`LinkOrigin` with angles in the requested convention.

    Args:
        transforms: ``(6, 4, 4)`` from :func:`six_transforms`.
        rpy: ``"urdf"`` or ``"upstream"``.

    Returns:
        The six link origins.
    """
    rpy = check_rpy_convention(rpy)
    T = np.asarray(transforms, dtype=np.float64)
    out: list[LinkOrigin] = []
    for name, Tk in zip(LINK_NAMES, T, strict=True):
        if rpy == "urdf":
            angles = tuple(float(v) for v in rpy_urdf_from_matrix(Tk[:3, :3]))
        else:
            angles = eigen_euler_xyz(Tk[:3, :3])
        xyz = (_clean(Tk[0, 3]), _clean(Tk[1, 3]), _clean(Tk[2, 3]))
        out.append(LinkOrigin(name, xyz, (_clean(angles[0]), _clean(angles[1]), _clean(angles[2]))))
    return tuple(out)


def correct_kinematics(dh: DHParameters, rpy: str = "urdf") -> UrKinematics:
    """Raw controller DH → the six corrected joint origins and the ``calib_`` hash.

    Args:
        dh: Raw controller DH (nominal + calibration deltas), six joints.
        rpy: ``"urdf"`` (default, exact through a URDF) or ``"upstream"`` (reproduce ur_calibration's angles).

    Returns:
        The kinematics file content.
    """
    rpy = check_rpy_convention(rpy)
    links = origins_from_transforms(six_transforms(correct_chain(dh)), rpy)
    h = calib_hash(dh.theta_rad, dh.d_m, dh.a_m, dh.alpha_rad)
    return UrKinematics(links=links, hash=h, rpy_convention=rpy)


def default_kinematics(model: str, rpy: str = "upstream") -> UrKinematics:
    """Regenerate ur_description's ``default_kinematics.yaml`` content for a model.

    Args:
        model: UR model name.
        rpy: ``"upstream"`` reproduces the checked-in files; ``"urdf"`` gives URDF-correct angles (identical
            rotations for nominal models).

    Returns:
        The kinematics content computed from the URSim nominal DH.
    """
    return correct_kinematics(nominal_dh(model), rpy)


def fk_origins(xyz_m: ArrayLike, rpy_rad: ArrayLike, q_rad: ArrayLike) -> FloatArray:
    """Forward kinematics the way a URDF evaluates six revolute joints with ``<axis xyz="0 0 1"/>``.

    ``T = Π_k T(xyz_k) · Rz(yaw_k)Ry(pitch_k)Rx(roll_k) · Rz(q_k)`` (URDF rpy semantics).

    Args:
        xyz_m: ``(6, 3)`` origins, metres.
        rpy_rad: ``(6, 3)`` URDF rpy, radians.
        q_rad: ``(6,)`` or ``(N, 6)`` joint positions, radians.

    Returns:
        ``(4, 4)`` or ``(N, 4, 4)`` base → flange transforms.
    """
    q = np.asarray(q_rad, dtype=np.float64)
    single = q.ndim == 1
    q2 = q.reshape(1, -1) if single else q
    origins = transform_from_xyz_rpy_urdf(np.asarray(xyz_m), np.asarray(rpy_rad))
    if origins.shape[0] != q2.shape[1]:
        raise ShapeMismatchError(f"fk_origins: {origins.shape[0]} origins but joint vectors {q.shape}")
    T = np.broadcast_to(np.eye(4), (q2.shape[0], 4, 4)).copy()
    for k in range(origins.shape[0]):
        Rq = np.zeros((q2.shape[0], 4, 4))
        Rq[:, :3, :3] = rot_z(q2[:, k])
        Rq[:, 3, 3] = 1.0
        T = T @ origins[k] @ Rq
    return np.asarray(T[0] if single else T, dtype=np.float64)


def split_chain(dh: DHParameters) -> FloatArray:
    """The uncorrected 12-matrix split chain ``D_1, A_1, …, D_6, A_6`` (for plots and diagnostics).

    Args:
        dh: Raw DH, six joints.

    Returns:
        ``(12, 4, 4)`` matrices.
    """
    if dh.n_joints != 6:
        raise ShapeMismatchError(f"UR DH parameters: expected 6 joints, got {dh.n_joints}")
    return np.array(_build_chain(dh), dtype=np.float64)


TEST_SET_3_DELTAS = DHParameters(
    theta_rad=(
        -2.41478068943590252e-07,
        1.60233952386694556,
        -1.68607190752171299,
        0.0837331147700118711,
        -1.01260355871157781e-07,
        3.91986209186123702e-08,
    ),
    a_m=(
        2.12234865571205891e-05,
        0.632017132627700651,
        0.00229833638891230319,
        -4.61409023720933908e-05,
        -6.39280053471801522e-05,
        0.0,
    ),
    d_m=(
        -0.000160188285741325043,
        439.140974079900957,
        -446.027059806332147,
        6.88618689642360149,
        -3.86588496858186748e-05,
        -0.00087908274257374186,
    ),
    alpha_rad=(
        -0.000650246557584166496,
        0.00139416666825590402,
        0.00693818880325995126,
        -0.000811641562390219562,
        0.000411120504570705592,
        0.0,
    ),
)
"""Calibration deltas of a real UR10e (ur_calibration's test set 3; d2 = 439 m once added to nominal)."""


@dataclass(frozen=True)
class NominalDeviation:
    """How far the corrected joint origins sit from a model's nominal geometry.

    Healthy calibrations deviate by about a millimetre / milliradian; metres mean the wrong model or a
    broken calibration.

    Attributes:
        model: The nominal model compared with.
        length_m: Largest ``|corrected − nominal|`` over d1 (shoulder.z), a2 (forearm.x), a3 (wrist_1.x),
            d4 (wrist_1.z), d5 (−wrist_2.y) and d6 (wrist_3.y), metres.
        length_field: Which of those is largest (e.g. ``"a2"``).
        angle_rad: Largest rotation angle between a corrected origin and the nominal one, radians.
    """

    model: str
    length_m: float
    length_field: str
    angle_rad: float


def deviation_from_nominal(kin: UrKinematics, model: str | None = None) -> NominalDeviation:
    """Compare corrected kinematics with a model's nominal geometry.

    Args:
        kin: Corrected kinematics (either rpy convention; rotations are compared as matrices).
        model: Model to compare with; None picks the model whose nominal lengths are closest.

    Returns:
        The largest length and angle deviation.
    """
    from .se3 import matrix_from_rpy_urdf, rotation_angle_between

    xyz = kin.xyz_array()
    measured = {
        "d1": xyz[0, 2],
        "a2": xyz[2, 0],
        "a3": xyz[3, 0],
        "d4": xyz[3, 2],
        "d5": -xyz[4, 1],
        "d6": xyz[5, 1],
    }

    def lengths(m: str) -> dict[str, float]:
        a2, a3, d1, d4, d5, d6 = UR_MODELS[m]
        return {"d1": d1, "a2": a2, "a3": a3, "d4": d4, "d5": d5, "d6": d6}

    if model is None:  # hypot: the Euclidean distance without overflow for absurd inputs
        model = min(
            UR_MODELS, key=lambda m: math.hypot(*(float(measured[k]) - v for k, v in lengths(m).items()))
        )
    nominal = lengths(model.strip().lower()) if model.strip().lower() in UR_MODELS else None
    if nominal is None:
        raise UsageError(f"unknown UR model {model!r}; valid: {', '.join(UR_MODELS)}")
    diffs = {k: abs(float(measured[k]) - v) for k, v in nominal.items()}
    field_name = max(diffs, key=lambda k: diffs[k])
    if kin.rpy_convention == "urdf":
        R = matrix_from_rpy_urdf(kin.rpy_array())
    else:
        R = np.array([_eigen_rpy_to_matrix(lk.rpy_rad) for lk in kin.links])
    nom_kin = correct_kinematics(nominal_dh(model), "urdf")
    R_nom = matrix_from_rpy_urdf(nom_kin.rpy_array())
    angle = float(np.max(rotation_angle_between(R, R_nom)))
    return NominalDeviation(model.strip().lower(), diffs[field_name], field_name, angle)


def _eigen_rpy_to_matrix(angles: tuple[float, float, float]) -> FloatArray:
    from .se3 import rot_x, rot_y

    return np.asarray(rot_x(angles[0]) @ rot_y(angles[1]) @ rot_z(angles[2]), dtype=np.float64)
