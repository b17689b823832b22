"""Geometric error model of a serial chain for kinematic identification (pure numpy, batched).

Parameters (all zero at the nominal model), in this order:

* ``base.x/y/z`` (m) and ``base.rx/ry/rz`` (rad): ``T_world_base = T_world_base_nominal · T(d) · Exp(r)``,
  where *world* is the frame the measurements are expressed in (a tracker's frame, or the base itself).
* for each movable joint ``J``, in chain order: ``J.offset`` (rad, or m for a prismatic joint) added to the
  reading, then ``J.x/y/z`` (m, added to ``<origin xyz>`` in the parent link's frame) and ``J.rx/ry/rz`` (rad, a
  rotation vector applied after the ``<origin rpy>`` rotation, in the joint's own frame):
  ``T_origin = T(xyz + d) · R(rpy) · Exp(r)`` and the joint moves by ``q + offset``;
* ``tool.x/y/z`` and ``tool.rx/ry/rz``: ``T_tip_tool = T_tip_tool_nominal · T(d) · Exp(r)``.

Fixed joints inside the chain get no parameters: an error there is the same as one on the next joint's origin
(or the tool), which the model already has, so the model stays complete. A complete model is redundant on
purpose (``base`` and the first origin overlap, a rotation about a joint's own axis is its offset, ...);
:mod:`robocal.core.identifiability` finds the identifiable base set and names the rest.

The identification Jacobian is analytic and exact at any parameter value (rotation parameters use the right
Jacobian of SO(3)); it is checked against central differences in the tests.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import ArrayLike

from ..errors import ShapeMismatchError
from .arrays import FloatArray
from .chain import ChainJoint, SerialChain, axis_motion
from .se3 import homogeneous, matrix_from_rotvec, matrix_from_rpy_urdf, rpy_urdf_from_matrix

__all__ = [
    "ORIGIN_KINDS",
    "ErrorModel",
    "KinematicParameter",
    "rpy_near",
    "so3_right_jacobian",
]


ORIGIN_KINDS: tuple[str, ...] = ("x", "y", "z", "rx", "ry", "rz")
"""The six parameters of a frame: translation (m) then rotation vector (rad)."""


@dataclass(frozen=True)
class KinematicParameter:
    """One error parameter.

    Attributes:
        name: ``"<group>.<kind>"``, e.g. ``"elbow_flex.offset"``, ``"base.z"``, ``"tool.rx"``.
        group: ``"base"``, ``"tool"`` or a joint name.
        kind: ``"offset"`` or one of :data:`ORIGIN_KINDS`.
        unit: ``"m"`` or ``"rad"``.
    """

    name: str
    group: str
    kind: str
    unit: str


def so3_right_jacobian(r: ArrayLike) -> FloatArray:
    """Right Jacobian of SO(3): ``Exp(r + δ) ≈ Exp(r) · Exp(J_r(r) δ)``, shape ``(3, 3)``."""
    v = np.asarray(r, dtype=np.float64)
    theta = float(np.linalg.norm(v))
    K = np.array([[0.0, -v[2], v[1]], [v[2], 0.0, -v[0]], [-v[1], v[0], 0.0]])
    if theta < 1e-6:
        return np.asarray(np.eye(3) - 0.5 * K + (K @ K) / 6.0, dtype=np.float64)
    a = (1.0 - math.cos(theta)) / theta**2
    b = (theta - math.sin(theta)) / theta**3
    return np.asarray(np.eye(3) - a * K + b * (K @ K), dtype=np.float64)


def _frame(x6: FloatArray) -> FloatArray:
    """``T(d) · Exp(r)`` for a 6-vector ``(d, r)``."""
    return homogeneous(matrix_from_rotvec(x6[3:]), x6[:3])


def rpy_near(R: ArrayLike, rpy_ref: ArrayLike) -> FloatArray:
    """URDF rpy of ``R`` chosen among its equivalent triples to lie closest to ``rpy_ref`` (radians).

    Keeps corrected origins recognisable: ``3.14159 0 -3.14159`` stays near itself rather than flipping to an
    equivalent triple.
    """
    ref = np.asarray(rpy_ref, dtype=np.float64)
    a = rpy_urdf_from_matrix(R)
    b = np.array([a[0] + math.pi, math.pi - a[1], a[2] + math.pi])
    best = a
    best_cost = math.inf
    for cand in (a, b):
        c = cand + 2.0 * math.pi * np.round((ref - cand) / (2.0 * math.pi))
        cost = float(np.sum((c - ref) ** 2))
        if cost < best_cost:
            best, best_cost = c, cost
    return np.asarray(best + 0.0, dtype=np.float64)


@dataclass(frozen=True, eq=False)
class ErrorModel:
    """A serial chain with base and tool frames and its error parameters.

    Attributes:
        chain: The nominal chain.
        T_world_base: ``(4, 4)`` nominal pose of the chain's base link in the measurement frame.
        T_tip_tool: ``(4, 4)`` nominal pose of the tool (marker, ball, probe tip) in the tip link's frame.
        parameters: The parameter list (see the module docstring for the order).
    """

    chain: SerialChain
    T_world_base: FloatArray = field(default_factory=lambda: np.eye(4))
    T_tip_tool: FloatArray = field(default_factory=lambda: np.eye(4))
    parameters: tuple[KinematicParameter, ...] = ()

    def __post_init__(self) -> None:
        for name in ("T_world_base", "T_tip_tool"):
            T = np.asarray(getattr(self, name), dtype=np.float64)
            if T.shape != (4, 4) or not np.all(np.isfinite(T)):
                raise ShapeMismatchError(f"ErrorModel.{name} must be a finite (4, 4) transform")
            object.__setattr__(self, name, T)
        if not self.parameters:
            params: list[KinematicParameter] = []
            unit = {"x": "m", "y": "m", "z": "m", "rx": "rad", "ry": "rad", "rz": "rad"}
            params += [KinematicParameter(f"base.{k}", "base", k, unit[k]) for k in ORIGIN_KINDS]
            for j in self.chain.movable:
                u = "rad" if j.type == "revolute" else "m"
                params.append(KinematicParameter(f"{j.name}.offset", j.name, "offset", u))
                params += [KinematicParameter(f"{j.name}.{k}", j.name, k, unit[k]) for k in ORIGIN_KINDS]
            params += [KinematicParameter(f"tool.{k}", "tool", k, unit[k]) for k in ORIGIN_KINDS]
            object.__setattr__(self, "parameters", tuple(params))

    @property
    def n_params(self) -> int:
        """Number of parameters."""
        return len(self.parameters)

    @property
    def names(self) -> tuple[str, ...]:
        """Parameter names in vector order."""
        return tuple(p.name for p in self.parameters)

    def index(self, name: str) -> int:
        """Position of parameter ``name`` in the vector."""
        return self.names.index(name)

    def _joint_start(self) -> dict[str, int]:
        """Index of each movable joint's ``offset`` parameter."""
        return {j.name: 6 + 7 * k for k, j in enumerate(self.chain.movable)}

    def _check_x(self, x: ArrayLike | None) -> FloatArray:
        if x is None:
            return np.zeros(self.n_params)
        xa = np.asarray(x, dtype=np.float64)
        if xa.shape != (self.n_params,):
            raise ShapeMismatchError(f"parameter vector has shape {xa.shape}; expected ({self.n_params},)")
        return xa

    def _walk(
        self, x: FloatArray, q: FloatArray
    ) -> tuple[FloatArray, list[tuple[str, FloatArray, FloatArray]]]:
        """FK keeping the frames the Jacobian needs.

        Returns ``T_world_tool`` ``(N, 4, 4)`` and, per parameter block, ``(kind, T_before, T_after)`` where
        ``T_before`` is the world pose of the frame the translation acts in and ``T_after`` the frame the
        rotation (or joint motion) acts in.
        """
        n = q.shape[0]
        blocks: list[tuple[str, FloatArray, FloatArray]] = []
        T_base = self.T_world_base @ _frame(x[:6])
        blocks.append(
            ("base", np.broadcast_to(self.T_world_base, (n, 4, 4)), np.broadcast_to(T_base, (n, 4, 4)))
        )
        T = np.broadcast_to(T_base, (n, 4, 4)).copy()
        starts = self._joint_start()
        k = 0
        for j in self.chain.joints:
            if not j.is_movable:
                T = T @ j.T_parent_joint()
                continue
            s = starts[j.name]
            T_o = self._origin(j, x[s + 1 : s + 7])
            T_joint = T @ T_o
            blocks.append((j.name, T, T_joint))
            T = T_joint @ axis_motion(j, q[:, k] + x[s])
            k += 1
        T_tool0 = T @ self.T_tip_tool
        T_tool = T_tool0 @ _frame(x[-6:])
        blocks.append(("tool", T_tool0, T_tool))
        return T_tool, blocks

    @staticmethod
    def _origin(j: ChainJoint, x6: FloatArray) -> FloatArray:
        R = matrix_from_rpy_urdf(np.array(j.origin_rpy_rad)) @ matrix_from_rotvec(x6[3:])
        return homogeneous(R, np.array(j.origin_xyz_m) + x6[:3])

    def _q(self, q_rad: ArrayLike) -> FloatArray:
        q = np.atleast_2d(np.asarray(q_rad, dtype=np.float64))
        if q.ndim != 2 or q.shape[1] != self.chain.n_q:
            raise ShapeMismatchError(f"joint positions {np.shape(q_rad)}; expected (N, {self.chain.n_q})")
        return q

    def tool_poses(self, q_rad: ArrayLike, x: ArrayLike | None = None) -> FloatArray:
        """``T_world_tool`` for joint readings ``q_rad`` ``(N, n_q)`` under parameters ``x``: ``(N, 4, 4)``."""
        T, _ = self._walk(self._check_x(x), self._q(q_rad))
        return T

    def points(self, q_rad: ArrayLike, x: ArrayLike | None = None) -> FloatArray:
        """``p_world_tool`` (m) for joint readings ``(N, n_q)``: ``(N, 3)``."""
        return self.tool_poses(q_rad, x)[:, :3, 3]

    def point_jacobian(
        self, q_rad: ArrayLike, x: ArrayLike | None = None, point_in_tool_m: ArrayLike | None = None
    ) -> tuple[FloatArray, FloatArray]:
        """Tool points and their exact derivatives with respect to every parameter.

        Args:
            q_rad: ``(N, n_q)`` joint readings.
            x: ``(P,)`` parameters (default: nominal, all zero).
            point_in_tool_m: ``(3,)`` or ``(N, 3)`` point(s) fixed in the tool frame (default: its origin), e.g.
                the corners of a target on the tool.

        Returns:
            ``p_world`` ``(N, 3)`` in metres, and ``∂p/∂x`` ``(N, 3, P)`` (m per m or m per rad).
        """
        xa = self._check_x(x)
        q = self._q(q_rad)
        T_tool, blocks = self._walk(xa, q)
        p = T_tool[:, :3, 3]
        if point_in_tool_m is not None:
            c = np.broadcast_to(np.asarray(point_in_tool_m, dtype=np.float64), p.shape)
            p = p + np.einsum("nij,nj->ni", T_tool[:, :3, :3], c)
        n = q.shape[0]
        J = np.zeros((n, 3, self.n_params))
        starts = self._joint_start()
        movable = {j.name: j for j in self.chain.movable}

        def rot_cols(T_after: FloatArray, r: FloatArray) -> FloatArray:
            w = T_after[:, :3, :3] @ so3_right_jacobian(r)  # (N, 3, 3): world axes of the rotation params
            arm = p - T_after[:, :3, 3]
            return np.asarray(
                np.cross(np.moveaxis(w, 2, 1), arm[:, None, :]).transpose(0, 2, 1), dtype=np.float64
            )

        for group, T_before, T_after in blocks:
            if group == "base":
                s, r = 0, xa[3:6]
            elif group == "tool":
                s, r = self.n_params - 6, xa[-3:]
            else:
                s = starts[group] + 1
                r = xa[s + 3 : s + 6]
                j = movable[group]
                axis_w = T_after[:, :3, :3] @ np.asarray(j.axis)
                if j.type == "revolute":
                    J[:, :, s - 1] = np.cross(axis_w, p - T_after[:, :3, 3])
                else:
                    J[:, :, s - 1] = axis_w
            J[:, :, s : s + 3] = T_before[:, :3, :3]
            J[:, :, s + 3 : s + 6] = rot_cols(T_after, r)
        return p, J

    def corrected(
        self, x: ArrayLike, *, fold_offsets: bool = True
    ) -> tuple[SerialChain, FloatArray, FloatArray]:
        """The chain, base and tool with parameters ``x`` applied.

        Args:
            x: ``(P,)`` parameters.
            fold_offsets: Put each joint offset into its ``<origin>`` (``T_origin · M(axis, offset)``), so the
                corrected chain gives the same poses from the same joint readings. When False the offsets are
                left out and must be added to the readings.

        Returns:
            ``(chain, T_world_base, T_tip_tool)``; origins keep rpy triples close to the nominal ones.
        """
        xa = self._check_x(x)
        starts = self._joint_start()
        joints = []
        for j in self.chain.joints:
            if not j.is_movable:
                joints.append(j)
                continue
            s = starts[j.name]
            T_o = self._origin(j, xa[s + 1 : s + 7])
            if fold_offsets:
                T_o = T_o @ axis_motion(j, np.array([xa[s]]))[0]
            rpy = rpy_near(T_o[:3, :3], j.origin_rpy_rad)
            joints.append(
                ChainJoint(
                    name=j.name,
                    type=j.type,
                    parent=j.parent,
                    child=j.child,
                    origin_xyz_m=(float(T_o[0, 3]), float(T_o[1, 3]), float(T_o[2, 3])),
                    origin_rpy_rad=(float(rpy[0]), float(rpy[1]), float(rpy[2])),
                    axis=j.axis,
                    lower=j.lower,
                    upper=j.upper,
                )
            )
        chain = SerialChain(tuple(joints), self.chain.base_link, self.chain.tip_link)
        return chain, self.T_world_base @ _frame(xa[:6]), self.T_tip_tool @ _frame(xa[-6:])

    def offsets(self, x: ArrayLike) -> dict[str, float]:
        """Joint zero offsets in ``x`` by joint name (rad, or m for prismatic joints)."""
        xa = self._check_x(x)
        return {name: float(xa[s]) for name, s in self._joint_start().items()}
