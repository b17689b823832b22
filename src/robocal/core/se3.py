"""Rotations, homogeneous transforms and Euler-angle conventions (pure numpy, vectorised).

Conventions:

* ``rot_x/rot_y/rot_z(angle_rad)`` return right-handed rotation matrices of shape ``(..., 3, 3)``.
* A homogeneous transform ``T_a_b`` (shape ``(..., 4, 4)``) maps coordinates in frame ``b`` to frame ``a``.
* URDF ``<origin rpy="r p y">`` means fixed-axis XYZ: ``R = Rz(y) · Ry(p) · Rx(r)``
  (:func:`matrix_from_rpy_urdf`, :func:`rpy_urdf_from_matrix`).
* Eigen's ``R.eulerAngles(0, 1, 2)`` means intrinsic X-Y'-Z'': ``R = Rx(a0) · Ry(a1) · Rz(a2)`` with
  ``a0 ∈ [0, π]``. Upstream ``ur_calibration`` writes these angles as URDF rpy, which is wrong in general;
  :func:`eigen_euler_xyz` reproduces Eigen 3.4's algorithm so that files can be compared with upstream.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import ArrayLike

from .arrays import FloatArray

__all__ = [
    "eigen_euler_xyz",
    "homogeneous",
    "matrix_from_rotvec",
    "matrix_from_rpy_urdf",
    "quaternion_from_matrix",
    "rot_x",
    "rot_y",
    "rot_z",
    "rotation_angle_between",
    "rotvec_from_matrix",
    "rpy_urdf_from_matrix",
    "transform_from_xyz_rpy_urdf",
]



def _angles(angle_rad: ArrayLike) -> FloatArray:
    return np.asarray(angle_rad, dtype=np.float64)


def _rotation_about_axis(angle_rad: ArrayLike, k: int) -> FloatArray:
    """Right-handed rotations about coordinate axis ``k`` (0 = x, 1 = y, 2 = z), shape ``S + (3, 3)``."""
    a = _angles(angle_rad)
    c, s = np.cos(a), np.sin(a)
    i, j = (k + 1) % 3, (k + 2) % 3
    out = np.zeros((*a.shape, 3, 3))
    out[..., k, k] = 1.0
    out[..., i, i] = c
    out[..., i, j] = -s
    out[..., j, i] = s
    out[..., j, j] = c
    return out


def rot_x(angle_rad: ArrayLike) -> FloatArray:
    """Rotation about x.

    Args:
        angle_rad: Angle(s) in radians, any shape ``S``.

    Returns:
        Rotation matrices, shape ``S + (3, 3)``.
    """
    return _rotation_about_axis(angle_rad, 0)


def rot_y(angle_rad: ArrayLike) -> FloatArray:
    """Rotation about y; shapes as in :func:`rot_x`."""
    return _rotation_about_axis(angle_rad, 1)


def rot_z(angle_rad: ArrayLike) -> FloatArray:
    """Rotation about z; shapes as in :func:`rot_x`."""
    return _rotation_about_axis(angle_rad, 2)


def homogeneous(R: ArrayLike, p_m: ArrayLike) -> FloatArray:
    """Assemble homogeneous transforms from rotations and translations.

    Args:
        R: Rotation matrices, shape ``(..., 3, 3)``.
        p_m: Translations in metres, shape ``(..., 3)`` (broadcast against ``R``).

    Returns:
        Transforms of shape ``(..., 4, 4)``.
    """
    R_arr = np.asarray(R, dtype=np.float64)
    p_arr = np.asarray(p_m, dtype=np.float64)
    batch = np.broadcast_shapes(R_arr.shape[:-2], p_arr.shape[:-1])
    out = np.zeros((*batch, 4, 4))
    out[..., :3, :3] = R_arr
    out[..., :3, 3] = p_arr
    out[..., 3, 3] = 1.0
    return out


def matrix_from_rpy_urdf(rpy_rad: ArrayLike) -> FloatArray:
    """URDF rpy → rotation matrix, ``R = Rz(yaw) · Ry(pitch) · Rx(roll)``.

    Args:
        rpy_rad: ``(..., 3)`` array of (roll, pitch, yaw) in radians.

    Returns:
        Rotation matrices, shape ``(..., 3, 3)``.
    """
    rpy = np.asarray(rpy_rad, dtype=np.float64)
    return rot_z(rpy[..., 2]) @ rot_y(rpy[..., 1]) @ rot_x(rpy[..., 0])


def rpy_urdf_from_matrix(R: ArrayLike) -> FloatArray:
    """Rotation matrix → URDF rpy (fixed-axis XYZ), the inverse of :func:`matrix_from_rpy_urdf`.

    ``roll = atan2(R21, R22)``, ``pitch = atan2(−R20, hypot(R21, R22))``, ``yaw = atan2(R10, R00)``;
    pitch lies in ``[−π/2, π/2]``. Zero angles are returned as ``+0.0`` (never ``-0.0``).

    Args:
        R: Rotation matrices, shape ``(..., 3, 3)``.

    Returns:
        ``(..., 3)`` array of (roll, pitch, yaw) in radians.
    """
    M = np.asarray(R, dtype=np.float64)
    roll = np.arctan2(M[..., 2, 1], M[..., 2, 2])
    pitch = np.arctan2(-M[..., 2, 0], np.hypot(M[..., 2, 1], M[..., 2, 2]))
    yaw = np.arctan2(M[..., 1, 0], M[..., 0, 0])
    out = np.stack([roll, pitch, yaw], axis=-1)
    return out + 0.0  # turns -0.0 into +0.0


def transform_from_xyz_rpy_urdf(xyz_m: ArrayLike, rpy_rad: ArrayLike) -> FloatArray:
    """A URDF ``<origin xyz rpy>`` as a homogeneous transform ``T(xyz) · Rz(y)Ry(p)Rx(r)``.

    Args:
        xyz_m: ``(..., 3)`` translation in metres.
        rpy_rad: ``(..., 3)`` URDF roll, pitch, yaw in radians.

    Returns:
        ``(..., 4, 4)`` transforms.
    """
    return homogeneous(matrix_from_rpy_urdf(rpy_rad), xyz_m)


def eigen_euler_xyz(R: ArrayLike) -> tuple[float, float, float]:
    """Eigen 3.4 ``R.eulerAngles(0, 1, 2)`` for one matrix (intrinsic X-Y'-Z'', ``R = Rx·Ry·Rz``).

    Reproduces Eigen's Graphics Gems IV branch operation by operation (including the choice of the first
    angle in ``[0, π]`` and the sign handling of zeros), so that robocal's ``--rpy upstream`` output matches
    the numbers ``ur_calibration`` writes. These angles are **not** URDF rpy.

    Args:
        R: One rotation matrix, shape ``(3, 3)``.

    Returns:
        The three angles ``(a0, a1, a2)`` in radians, as Eigen returns them.
    """
    M = np.asarray(R, dtype=np.float64)
    c = [[float(M[r, k]) for k in range(3)] for r in range(3)]
    # i = 0, j = 1, k = 2, odd = 0 for the axis sequence (0, 1, 2).
    r0 = math.atan2(c[1][2], c[2][2])
    c2 = math.sqrt(c[0][0] * c[0][0] + c[0][1] * c[0][1])
    if r0 > 0.0:
        r0 -= math.pi
        r1 = math.atan2(-c[0][2], -c2)
    else:
        r1 = math.atan2(-c[0][2], c2)
    s1 = math.sin(r0)
    c1 = math.cos(r0)
    r2 = math.atan2(s1 * c[2][0] - c1 * c[1][0], c1 * c[1][1] - s1 * c[2][1])
    return (-r0, -r1, -r2)


def rotation_angle_between(R_a: ArrayLike, R_b: ArrayLike) -> FloatArray:
    """Angle of the relative rotation ``R_aᵀ·R_b``, accurate for tiny angles.

    Uses ``‖R_a − R_b‖_F = 2√2·sin(θ/2)``, which keeps full relative precision near zero (``arccos`` of the
    trace would bottom out at ~1e-8 rad).

    Args:
        R_a: ``(..., 3, 3)`` rotations.
        R_b: ``(..., 3, 3)`` rotations.

    Returns:
        ``(...)`` angles in radians, in ``[0, π]``.
    """
    diff = np.asarray(R_a, dtype=np.float64) - np.asarray(R_b, dtype=np.float64)
    norm = np.sqrt(np.sum(diff * diff, axis=(-2, -1)))
    return np.asarray(2.0 * np.arcsin(np.clip(norm / (2.0 * math.sqrt(2.0)), 0.0, 1.0)), dtype=np.float64)


def matrix_from_rotvec(rotvec_rad: ArrayLike) -> FloatArray:
    """Rotation vector (axis · angle, as the UR controller reports Rx, Ry, Rz) → rotation matrix.

    Args:
        rotvec_rad: ``(..., 3)`` rotation vectors, radians.

    Returns:
        ``(..., 3, 3)`` rotation matrices (Rodrigues' formula, exact near zero).
    """
    v = np.asarray(rotvec_rad, dtype=np.float64)
    theta = np.linalg.norm(v, axis=-1)
    small = theta < 1e-8
    safe = np.where(small, 1.0, theta)
    a = np.where(small, 1.0 - theta**2 / 6.0, np.sin(theta) / safe)
    b = np.where(small, 0.5 - theta**2 / 24.0, (1.0 - np.cos(theta)) / (safe * safe))
    K = np.zeros((*v.shape[:-1], 3, 3))
    K[..., 0, 1], K[..., 0, 2] = -v[..., 2], v[..., 1]
    K[..., 1, 0], K[..., 1, 2] = v[..., 2], -v[..., 0]
    K[..., 2, 0], K[..., 2, 1] = -v[..., 1], v[..., 0]
    eye = np.broadcast_to(np.eye(3), K.shape)
    return np.asarray(eye + a[..., None, None] * K + b[..., None, None] * (K @ K), dtype=np.float64)


def quaternion_from_matrix(R: ArrayLike) -> tuple[float, float, float, float]:
    """Rotation matrix → quaternion ``(w, x, y, z)`` with ``w ≥ 0`` (Shepperd: the largest component first).

    Args:
        R: One rotation matrix, shape ``(3, 3)``.

    Returns:
        ``(w, x, y, z)``, a unit quaternion up to the rounding of ``R`` (not renormalised).
    """
    M = np.asarray(R, dtype=np.float64)
    tr = M[0, 0] + M[1, 1] + M[2, 2]
    if tr > 0:
        s = 2.0 * math.sqrt(tr + 1.0)
        w, x, y, z = 0.25 * s, (M[2, 1] - M[1, 2]) / s, (M[0, 2] - M[2, 0]) / s, (M[1, 0] - M[0, 1]) / s
    elif M[0, 0] >= M[1, 1] and M[0, 0] >= M[2, 2]:
        s = 2.0 * math.sqrt(1.0 + M[0, 0] - M[1, 1] - M[2, 2])
        w, x, y, z = (M[2, 1] - M[1, 2]) / s, 0.25 * s, (M[0, 1] + M[1, 0]) / s, (M[0, 2] + M[2, 0]) / s
    elif M[1, 1] >= M[2, 2]:
        s = 2.0 * math.sqrt(1.0 + M[1, 1] - M[0, 0] - M[2, 2])
        w, x, y, z = (M[0, 2] - M[2, 0]) / s, (M[0, 1] + M[1, 0]) / s, 0.25 * s, (M[1, 2] + M[2, 1]) / s
    else:
        s = 2.0 * math.sqrt(1.0 + M[2, 2] - M[0, 0] - M[1, 1])
        w, x, y, z = (M[1, 0] - M[0, 1]) / s, (M[0, 2] + M[2, 0]) / s, (M[1, 2] + M[2, 1]) / s, 0.25 * s
    if w < 0:
        w, x, y, z = -w, -x, -y, -z
    return (float(w), float(x), float(y), float(z))


def rotvec_from_matrix(R: ArrayLike) -> FloatArray:
    """Rotation matrix → rotation vector (angle in ``[0, π]``), via a unit quaternion for full precision.

    Args:
        R: One rotation matrix, shape ``(3, 3)``.

    Returns:
        ``(3,)`` rotation vector, radians.
    """
    w, x, y, z = quaternion_from_matrix(R)
    vnorm = math.sqrt(x * x + y * y + z * z)
    if vnorm == 0.0:
        return np.zeros(3)
    angle = 2.0 * math.atan2(vnorm, w)
    return np.array([x, y, z]) * (angle / vnorm)
