"""The Universal Robots chain correction of ``ur_calibration``, operation by operation (pure math, no I/O).

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

import numpy as np
from numpy.typing import ArrayLike

from ..errors import InvalidCalibrationError, ShapeMismatchError
from .arrays import FloatArray
from .dh import DHParameters

__all__ = ["MIN_ABS_COS_ALPHA", "correct_chain", "six_transforms", "split_chain"]

Mat = list[list[float]]

MIN_ABS_COS_ALPHA = 1e-3
"""Smallest ``|cos α|`` of joints 2 and 3 the correction accepts (α within 0.057° of ±π/2 is refused)."""


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
