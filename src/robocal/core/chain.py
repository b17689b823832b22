"""Serial kinematic chains the way a URDF evaluates them (pure numpy, batched over poses).

A chain runs from a base link to a tip link through revolute, prismatic and fixed joints. Joint ``k`` maps
its child link's frame to its parent's as ``T_parent_child = T(xyz) · Rz(y)Ry(p)Rx(r) · M(axis, q)`` where
``M`` is a rotation by ``q`` about ``axis`` (revolute, continuous) or a translation ``q·axis`` (prismatic), and
the identity for fixed joints. This is robocal's one URDF-chain forward kinematics: the kinematic
identification model (:mod:`robocal.core.kinematic_errors`) is built on it, and any URDF-based FK should call
:func:`fk_chain`.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from ..errors import InvalidCalibrationError, JointOutOfRangeError, ShapeMismatchError, UsageError
from .arrays import FloatArray, Vec3
from .se3 import rot_x, rot_y, rot_z, transform_from_xyz_rpy_urdf

__all__ = [
    "JOINT_TYPES",
    "URDF_JOINT_TYPES",
    "ChainJoint",
    "SerialChain",
    "axis_motion",
    "fk_chain",
    "rotation_about_axis",
]


URDF_JOINT_TYPES: tuple[str, ...] = ("revolute", "continuous", "prismatic", "fixed", "floating", "planar")
"""Joint kinds a URDF may name (what :class:`ChainJoint` takes)."""
JOINT_TYPES: tuple[str, ...] = ("revolute", "prismatic", "fixed")
"""Joint kinds of a chain (URDF ``continuous`` joints are ``revolute`` without limits)."""


@dataclass(frozen=True)
class ChainJoint:
    """One URDF joint: what the URDF parser reads (:mod:`robocal.formats.urdf`) and what a chain evaluates.

    A :class:`SerialChain` takes ``revolute``, ``prismatic`` and ``fixed`` joints only (its builders turn a
    URDF's ``continuous`` joint into an unlimited ``revolute`` one). A movable joint's axis is made a unit
    vector here; a zero axis is accepted here (a URDF may say so) and refused by :class:`SerialChain`.

    Attributes:
        name: Joint name (as in the URDF).
        type: ``revolute``, ``continuous``, ``prismatic``, ``fixed``, ``floating`` or ``planar``.
        parent: Parent link name.
        child: Child link name.
        origin_xyz_m: ``<origin xyz>``, metres, in the parent link's frame.
        origin_rpy_rad: ``<origin rpy>``, radians, URDF convention ``Rz(yaw)·Ry(pitch)·Rx(roll)``.
        axis: ``<axis xyz>``, unit vector in the joint frame (URDF's default ``(1, 0, 0)``; ignored for fixed
            joints).
        lower: ``<limit lower>`` (rad or m), None when absent (unlimited).
        upper: ``<limit upper>`` (rad or m), None when absent (unlimited).
        velocity: ``<limit velocity>`` (rad/s or m/s), None when absent.
        effort: ``<limit effort>`` (N·m or N), None when absent.
        mimic: Name of the mimicked joint (``<mimic joint>``), or None.
    """

    name: str
    type: str
    parent: str
    child: str
    origin_xyz_m: Vec3 = (0.0, 0.0, 0.0)
    origin_rpy_rad: Vec3 = (0.0, 0.0, 0.0)
    axis: Vec3 = (1.0, 0.0, 0.0)
    lower: float | None = None
    upper: float | None = None
    velocity: float | None = None
    effort: float | None = None
    mimic: str | None = None

    def __post_init__(self) -> None:
        if self.type not in URDF_JOINT_TYPES:
            raise UsageError(
                f"joint {self.name!r}: type {self.type!r}; a URDF joint is {', '.join(URDF_JOINT_TYPES)}"
            )
        values = (*self.origin_xyz_m, *self.origin_rpy_rad, *self.axis)
        if len(values) != 9 or not all(math.isfinite(v) for v in values):
            raise InvalidCalibrationError(f"joint {self.name!r}: origin and axis need 3 finite numbers each")
        if self.type != "fixed":
            n = math.sqrt(sum(a * a for a in self.axis))
            if n >= 1e-12 and abs(n - 1.0) > 1e-12:
                object.__setattr__(self, "axis", tuple(a / n for a in self.axis))

    @property
    def is_movable(self) -> bool:
        """True for joints with a degree of freedom (not fixed)."""
        return self.type != "fixed"

    def T_parent_joint(self) -> FloatArray:
        """The constant ``<origin>`` transform (parent link → joint frame before motion), ``(4, 4)``."""
        return transform_from_xyz_rpy_urdf(np.array(self.origin_xyz_m), np.array(self.origin_rpy_rad))


@dataclass(frozen=True)
class SerialChain:
    """Joints from ``base_link`` to ``tip_link`` in order, each one's parent the previous one's child.

    Attributes:
        joints: The joints, base first.
        base_link: Link whose frame poses are expressed in.
        tip_link: Last link of the chain.
    """

    joints: tuple[ChainJoint, ...]
    base_link: str
    tip_link: str

    def __post_init__(self) -> None:
        link = self.base_link
        for j in self.joints:
            if j.type not in JOINT_TYPES:
                raise UsageError(f"joint {j.name!r}: type {j.type!r}; a chain takes {', '.join(JOINT_TYPES)}")
            if j.is_movable and math.sqrt(sum(a * a for a in j.axis)) < 1e-12:
                raise InvalidCalibrationError(f"joint {j.name!r}: axis is the zero vector")
            if j.parent != link:
                raise UsageError(f"chain: joint {j.name!r} has parent {j.parent!r}, expected {link!r}")
            link = j.child
        if link != self.tip_link:
            raise UsageError(f"chain ends at {link!r}, expected tip link {self.tip_link!r}")
        names = [j.name for j in self.joints]
        if len(set(names)) != len(names):
            raise UsageError(f"chain: duplicate joint names in {names}")

    @property
    def movable(self) -> tuple[ChainJoint, ...]:
        """Revolute and prismatic joints in chain order (the columns of a joint array ``q``)."""
        return tuple(j for j in self.joints if j.is_movable)

    @property
    def joint_names(self) -> tuple[str, ...]:
        """Names of the movable joints, the order of ``q``."""
        return tuple(j.name for j in self.movable)

    @property
    def n_q(self) -> int:
        """Number of movable joints."""
        return len(self.movable)

    def limits(self) -> tuple[FloatArray, FloatArray]:
        """``(lower, upper)`` arrays over the movable joints, ``±inf`` where a limit is missing."""
        lo = np.array([-math.inf if j.lower is None else j.lower for j in self.movable])
        up = np.array([math.inf if j.upper is None else j.upper for j in self.movable])
        return lo, up

    def check_q(self, q_rad: ArrayLike, *, tolerance: float = 1e-9, what: str = "pose") -> FloatArray:
        """Validate joint positions: shape ``(N, n_q)``, finite, inside the limits.

        Args:
            q_rad: ``(n_q,)`` or ``(N, n_q)`` joint positions (rad or m).
            tolerance: Allowed excursion beyond a limit.
            what: How messages name a row.

        Returns:
            ``(N, n_q)`` float array.

        Raises:
            ShapeMismatchError: Wrong number of columns.
            InvalidCalibrationError: A NaN or infinite value (names the row and joint).
            JointOutOfRangeError: A value outside the joint's limits (names the row and joint).
        """
        q = np.atleast_2d(np.asarray(q_rad, dtype=np.float64))
        if q.ndim != 2 or q.shape[1] != self.n_q:
            raise ShapeMismatchError(
                f"joint positions have shape {np.shape(q_rad)}; expected (N, {self.n_q}) for "
                f"{', '.join(self.joint_names)}"
            )
        bad = ~np.isfinite(q)
        if bad.any():
            i, k = (int(v) for v in np.argwhere(bad)[0])
            raise InvalidCalibrationError(f"{what} {i + 1}: joint {self.joint_names[k]} is {q[i, k]}")
        lo, up = self.limits()
        out = (q < lo - tolerance) | (q > up + tolerance)
        if out.any():
            i, k = (int(v) for v in np.argwhere(out)[0])
            raise JointOutOfRangeError(
                f"{what} {i + 1}: joint {self.joint_names[k]} = {q[i, k]:.6g} is outside its limits "
                f"[{lo[k]:.6g}, {up[k]:.6g}]"
            )
        return q


_COORDINATE_ROTATIONS = (rot_x, rot_y, rot_z)


def rotation_about_axis(axis: ArrayLike, angle_rad: ArrayLike) -> FloatArray:
    """Rotations by ``angle_rad`` about a unit ``axis``, shape ``S + (3, 3)`` for angles of shape S.

    A coordinate axis (``±x``, ``±y``, ``±z``) gives the exact ``cos``/``sin`` entries of
    :func:`~robocal.core.se3.rot_z` and its siblings; any other axis goes through Rodrigues' formula.
    """
    k = np.asarray(axis, dtype=np.float64)
    a = np.asarray(angle_rad, dtype=np.float64)
    nonzero = np.flatnonzero(k)
    if nonzero.size == 1 and abs(float(k[nonzero[0]])) == 1.0:
        i = int(nonzero[0])
        return _COORDINATE_ROTATIONS[i](a if k[i] > 0 else -a)
    K = np.array([[0.0, -k[2], k[1]], [k[2], 0.0, -k[0]], [-k[1], k[0], 0.0]])
    s = np.sin(a)[..., None, None]
    c = np.cos(a)[..., None, None]
    return np.asarray(np.eye(3) + s * K + (1.0 - c) * (K @ K), dtype=np.float64)


def axis_motion(joint: ChainJoint, q: ArrayLike) -> FloatArray:
    """The joint's motion transform ``M(axis, q)`` for positions ``q`` of shape ``(N,)``: ``(N, 4, 4)``."""
    qa = np.asarray(q, dtype=np.float64)
    out = np.zeros((*qa.shape, 4, 4))
    out[..., 3, 3] = 1.0
    if joint.type == "revolute":
        out[..., :3, :3] = rotation_about_axis(joint.axis, qa)
    else:
        out[..., :3, :3] = np.eye(3)
        if joint.type == "prismatic":
            out[..., :3, 3] = qa[..., None] * np.asarray(joint.axis)
    return out


def fk_chain(chain: SerialChain, q_rad: ArrayLike, origins: Sequence[ArrayLike] | None = None) -> FloatArray:
    """Forward kinematics ``T_base_tip`` of a serial chain, batched.

    Args:
        chain: The chain.
        q_rad: ``(n_q,)`` or ``(N, n_q)`` positions of the movable joints in chain order (rad or m).
        origins: Optional ``(4, 4)`` origin transforms replacing each joint's ``<origin>`` (one per joint).

    Returns:
        ``(4, 4)`` or ``(N, 4, 4)`` transforms from the tip link's frame to the base link's frame.
    """
    q = np.asarray(q_rad, dtype=np.float64)
    single = q.ndim == 1
    q2 = q.reshape(1, -1) if single else q
    if q2.ndim != 2 or q2.shape[1] != chain.n_q:
        raise ShapeMismatchError(f"fk_chain: joint positions {q.shape}; expected (N, {chain.n_q})")
    if origins is not None and len(origins) != len(chain.joints):
        raise ShapeMismatchError(f"fk_chain: {len(origins)} origins for {len(chain.joints)} joints")
    T = np.broadcast_to(np.eye(4), (q2.shape[0], 4, 4)).copy()
    k = 0
    for i, j in enumerate(chain.joints):
        T = T @ (j.T_parent_joint() if origins is None else np.asarray(origins[i], dtype=np.float64))
        if j.is_movable:
            T = T @ axis_motion(j, q2[:, k])
            k += 1
    return np.asarray(T[0] if single else T, dtype=np.float64)
