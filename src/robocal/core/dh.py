"""Denavit-Hartenberg model and batched forward kinematics (pure numpy).

Joint ``i`` contributes ``Rz(θ_i + q_i) · Tz(d_i) · Tx(a_i) · Rx(α_i)`` (standard DH, the order UR's
controller and ``ur_calibration`` use). :func:`fk_dh` evaluates the chain for many joint vectors at once.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from ..errors import InvalidCalibrationError, ShapeMismatchError
from .arrays import FloatArray

__all__ = ["DHParameters", "dh_joint_transforms", "fk_dh", "fk_dh_loop"]



def _tuple6(values: Sequence[float] | ArrayLike, name: str, n: int) -> tuple[float, ...]:
    arr = np.asarray(values, dtype=np.float64).reshape(-1)
    if arr.shape != (n,):
        raise ShapeMismatchError(f"DH parameter {name}: expected {n} values, got {arr.size}")
    if not np.all(np.isfinite(arr)):
        bad = int(np.flatnonzero(~np.isfinite(arr))[0])
        raise InvalidCalibrationError(f"DH parameter {name}[{bad}] is {arr[bad]}; expected a finite number")
    return tuple(float(v) for v in arr)  # raw values, signed zeros included (the calib_ hash prints "-0")


@dataclass(frozen=True)
class DHParameters:
    """DH parameters of a serial arm (six joints for UR arms).

    Attributes:
        theta_rad: Joint angle offsets θ_i, radians.
        a_m: Link lengths a_i along x, metres.
        d_m: Link offsets d_i along z, metres.
        alpha_rad: Link twists α_i about x, radians.

    Values are kept exactly as given (a ``-0.0`` from the controller stays ``-0.0``, because the driver's
    ``calib_`` hash prints it as ``-0``); output files never contain ``-0``.
    """

    theta_rad: tuple[float, ...]
    a_m: tuple[float, ...]
    d_m: tuple[float, ...]
    alpha_rad: tuple[float, ...]

    def __post_init__(self) -> None:
        n = len(self.theta_rad)
        if n == 0:
            raise ShapeMismatchError("DH parameters: at least one joint is required")
        object.__setattr__(self, "theta_rad", _tuple6(self.theta_rad, "theta", n))
        object.__setattr__(self, "a_m", _tuple6(self.a_m, "a", n))
        object.__setattr__(self, "d_m", _tuple6(self.d_m, "d", n))
        object.__setattr__(self, "alpha_rad", _tuple6(self.alpha_rad, "alpha", n))

    @property
    def n_joints(self) -> int:
        """Number of joints."""
        return len(self.theta_rad)

    def __add__(self, other: DHParameters) -> DHParameters:
        """Element-wise sum (nominal parameters + controller calibration deltas)."""
        if other.n_joints != self.n_joints:
            raise ShapeMismatchError(f"DH sum: {self.n_joints} joints + {other.n_joints} joints")

        def add(u: tuple[float, ...], v: tuple[float, ...]) -> tuple[float, ...]:
            return tuple(x + y for x, y in zip(u, v, strict=True))

        return DHParameters(
            theta_rad=add(self.theta_rad, other.theta_rad),
            a_m=add(self.a_m, other.a_m),
            d_m=add(self.d_m, other.d_m),
            alpha_rad=add(self.alpha_rad, other.alpha_rad),
        )

    def arrays(self) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray]:
        """(θ, a, d, α) as float64 arrays of shape ``(n,)``."""
        return (
            np.array(self.theta_rad),
            np.array(self.a_m),
            np.array(self.d_m),
            np.array(self.alpha_rad),
        )


def _joint_matrices(dh: DHParameters, q_rad: FloatArray) -> FloatArray:
    """Per-joint DH transforms, shape ``(N, n, 4, 4)`` for ``q_rad`` of shape ``(N, n)``."""
    theta, a, d, alpha = dh.arrays()
    th = q_rad + theta
    ct, st = np.cos(th), np.sin(th)
    ca, sa = np.cos(alpha), np.sin(alpha)
    out = np.zeros((*q_rad.shape, 4, 4))
    out[..., 0, 0] = ct
    out[..., 0, 1] = -st * ca
    out[..., 0, 2] = st * sa
    out[..., 0, 3] = a * ct
    out[..., 1, 0] = st
    out[..., 1, 1] = ct * ca
    out[..., 1, 2] = -ct * sa
    out[..., 1, 3] = a * st
    out[..., 2, 1] = sa
    out[..., 2, 2] = ca
    out[..., 2, 3] = d
    out[..., 3, 3] = 1.0
    return out


def dh_joint_transforms(dh: DHParameters, q_rad: ArrayLike) -> FloatArray:
    """Per-joint transforms ``Rz(θ_i + q_i)·Tz(d_i)·Tx(a_i)·Rx(α_i)``.

    Args:
        dh: The DH model (n joints).
        q_rad: Joint positions, shape ``(n,)`` or ``(N, n)``, radians.

    Returns:
        Transforms of shape ``q_rad.shape + (4, 4)``.
    """
    q = np.asarray(q_rad, dtype=np.float64)
    if q.shape[-1:] != (dh.n_joints,):
        raise ShapeMismatchError(f"joint vector: expected (..., {dh.n_joints}), got {q.shape}")
    return _joint_matrices(dh, q)


def _link_constants(dh: DHParameters) -> FloatArray:
    """``Tz(d_i)·Tx(a_i)·Rx(α_i)`` per joint, shape ``(n, 4, 4)`` (the part that does not depend on q)."""
    _, a, d, alpha = dh.arrays()
    ca, sa = np.cos(alpha), np.sin(alpha)
    M = np.zeros((dh.n_joints, 4, 4))
    M[:, 0, 0] = 1.0
    M[:, 0, 3] = a
    M[:, 1, 1] = ca
    M[:, 1, 2] = -sa
    M[:, 2, 1] = sa
    M[:, 2, 2] = ca
    M[:, 2, 3] = d
    M[:, 3, 3] = 1.0
    return M


def fk_dh(dh: DHParameters, q_rad: ArrayLike, *, chunk: int = 65_536) -> FloatArray:
    """Batched forward kinematics ``T_base_flange`` of the DH chain.

    Each joint multiplies the running transform by ``Rz(θ_i + q_i)`` (an elementwise update of two columns)
    and then by the constant ``Tz(d_i)·Tx(a_i)·Rx(α_i)`` (one matrix product over the whole chunk), so the
    cost is a few vector operations per joint instead of a stacked 4×4 product per joint vector.

    Args:
        dh: The DH model (n joints).
        q_rad: Joint positions, shape ``(n,)`` or ``(N, n)``, radians.
        chunk: Joint vectors processed at once (bounds temporary memory to ~``chunk·200`` bytes).

    Returns:
        ``T_base_flange`` of shape ``(4, 4)`` or ``(N, 4, 4)`` (metres).
    """
    q = np.asarray(q_rad, dtype=np.float64)
    single = q.ndim == 1
    q2 = q.reshape(1, -1) if single else q
    if q2.ndim != 2 or q2.shape[1] != dh.n_joints:
        raise ShapeMismatchError(f"joint vectors: expected (N, {dh.n_joints}), got {q.shape}")
    theta = np.array(dh.theta_rad)
    M = _link_constants(dh)
    n_total = q2.shape[0]
    out = np.zeros((n_total, 4, 4))
    out[:, 3, 3] = 1.0
    step = max(1, chunk)
    for start in range(0, n_total, step):
        qc = q2[start : start + step]
        m = qc.shape[0]
        T = np.zeros((m, 3, 4))  # top three rows of the running transform
        T[:, 0, 0] = T[:, 1, 1] = T[:, 2, 2] = 1.0
        for i in range(dh.n_joints):
            th = qc[:, i] + theta[i]
            c = np.cos(th)[:, None]
            s = np.sin(th)[:, None]
            col0 = T[:, :, 0].copy()
            col1 = T[:, :, 1]
            T[:, :, 0] = col0 * c + col1 * s
            T[:, :, 1] = col1 * c - col0 * s
            T = (T.reshape(-1, 4) @ M[i]).reshape(m, 3, 4)
        out[start : start + m, :3, :] = T
    return out[0] if single else out


def fk_dh_loop(dh: DHParameters, q_rad: Sequence[float]) -> list[list[float]]:
    """Reference forward kinematics for one joint vector in plain Python (baseline for the benchmark).

    Args:
        dh: The DH model.
        q_rad: One joint vector, radians.

    Returns:
        ``T_base_flange`` as nested lists (4×4).
    """
    T = [[1.0, 0.0, 0.0, 0.0], [0.0, 1.0, 0.0, 0.0], [0.0, 0.0, 1.0, 0.0], [0.0, 0.0, 0.0, 1.0]]
    for i in range(dh.n_joints):
        th = dh.theta_rad[i] + q_rad[i]
        ct, st = math.cos(th), math.sin(th)
        ca, sa = math.cos(dh.alpha_rad[i]), math.sin(dh.alpha_rad[i])
        a, d = dh.a_m[i], dh.d_m[i]
        A = [
            [ct, -st * ca, st * sa, a * ct],
            [st, ct * ca, -ct * sa, a * st],
            [0.0, sa, ca, d],
            [0.0, 0.0, 0.0, 1.0],
        ]
        T = [[sum(T[r][k] * A[k][c] for k in range(4)) for c in range(4)] for r in range(4)]
    return T
