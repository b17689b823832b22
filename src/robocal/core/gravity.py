"""Gravity torque per joint from a URDF's inertials (masses and centres of mass), pure numpy.

A :class:`GravityModel` is a URDF's kinematic tree (its joints as :class:`~robocal.core.chain.ChainJoint`) plus
the mass and centre of mass of every link that has an ``<inertial>``. The torque gravity puts on a movable
joint ``i`` is the moment of the weight of every link below it about the joint's axis::

    τ_i(q) = a_i · Σ_{l below i} (c_l − o_i) × (m_l · g)        (revolute)
    τ_i(q) = a_i · Σ_{l below i} m_l · g                        (prismatic)

with ``o_i`` and ``a_i`` the joint's origin and unit axis and ``c_l`` the link's centre of mass, all in the root
link's frame at pose ``q`` (each link placed by :func:`~robocal.core.chain.fk_chain` along the chain from the
root), and ``g`` the gravity vector in the root frame (``(0, 0, −9.80665)`` m/s² for an upright base). The sign is
that of the joint: a positive torque accelerates the joint towards +q — the convention of the stop search
(:mod:`robocal.core.stop_search`: ``q = q_surface + (τ_motor + τ_g)/k`` at a stop).

With every other joint held, the links below a revolute joint turn rigidly about its axis, so its gravity
torque is exactly ``τ(q) = A·cos q + B·sin q`` (:class:`JointGravity`, two evaluations of the model): cheap
enough for a simulator's integration step and for the stop-zero correction (:mod:`robocal.core.stop_zero`).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import ArrayLike

from ..errors import InvalidCalibrationError, JointMismatchError, ShapeMismatchError
from .arrays import FloatArray, Vec3
from .chain import ChainJoint, SerialChain, fk_chain

__all__ = [
    "STANDARD_GRAVITY_M_S2",
    "GravityModel",
    "JointGravity",
    "LinkInertial",
    "gravity_torques",
    "joint_gravity",
]


STANDARD_GRAVITY_M_S2: Vec3 = (0.0, 0.0, -9.80665)
"""Gravity in the root frame of an upright robot (z up), m/s²."""


@dataclass(frozen=True)
class LinkInertial:
    """A link's mass and centre of mass (a URDF ``<inertial>``; the inertia tensor plays no part in gravity).

    Attributes:
        link: Link name.
        mass_kg: Mass (≥ 0, finite).
        com_xyz_m: Centre of mass in the link's frame (``<inertial><origin xyz>``), metres.
    """

    link: str
    mass_kg: float
    com_xyz_m: Vec3 = (0.0, 0.0, 0.0)

    def __post_init__(self) -> None:
        if not (math.isfinite(self.mass_kg) and self.mass_kg >= 0):
            raise InvalidCalibrationError(
                f"link {self.link!r}: mass must be a finite number ≥ 0, not {self.mass_kg!r}"
            )
        if len(self.com_xyz_m) != 3 or not all(math.isfinite(v) for v in self.com_xyz_m):
            raise InvalidCalibrationError(f"link {self.link!r}: centre of mass needs 3 finite numbers")


@dataclass(frozen=True)
class GravityModel:
    """A kinematic tree with link masses: what :func:`gravity_torques` evaluates.

    Attributes:
        joints: Every joint of the tree (any order; each link is the child of at most one joint).
        inertials: Links with mass (links without one weigh nothing).
        root_link: The tree's root (the frame of ``gravity_m_s2``).
        gravity_m_s2: Gravity in the root frame.
    """

    joints: tuple[ChainJoint, ...]
    inertials: tuple[LinkInertial, ...]
    root_link: str
    gravity_m_s2: Vec3 = STANDARD_GRAVITY_M_S2
    _chains: dict[str, SerialChain] = field(init=False, repr=False, compare=False)
    _below: dict[str, tuple[str, ...]] = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        if len(self.gravity_m_s2) != 3 or not all(math.isfinite(v) for v in self.gravity_m_s2):
            raise InvalidCalibrationError("gravity model: the gravity vector needs 3 finite numbers")
        by_child: dict[str, ChainJoint] = {}
        for j in self.joints:
            if j.child in by_child:
                raise JointMismatchError(
                    f"gravity model: link {j.child!r} is the child of {by_child[j.child].name!r} and {j.name!r}"
                )
            by_child[j.child] = j
        names = [j.name for j in self.joints]
        if len(set(names)) != len(names):
            raise JointMismatchError("gravity model: duplicate joint names")
        seen: set[str] = set()
        for inertial in self.inertials:
            if inertial.link in seen:
                raise JointMismatchError(f"gravity model: link {inertial.link!r} has two inertials")
            seen.add(inertial.link)

        def path(link: str) -> tuple[ChainJoint, ...]:
            out: list[ChainJoint] = []
            while link != self.root_link:
                j = by_child.get(link)
                if j is None or len(out) > len(self.joints):
                    raise JointMismatchError(
                        f"gravity model: link {link!r} is not below the root {self.root_link!r}"
                    )
                out.append(j)
                link = j.parent
            return tuple(reversed(out))

        chains: dict[str, SerialChain] = {}
        for link in {i.link for i in self.inertials} | {j.child for j in self.joints if j.is_movable}:
            chains[link] = SerialChain(path(link), self.root_link, link)
        below: dict[str, list[str]] = {j.name: [] for j in self.joints if j.is_movable}
        for inertial in self.inertials:
            for j in chains[inertial.link].joints:
                if j.is_movable:
                    below[j.name].append(inertial.link)
        object.__setattr__(self, "_chains", chains)
        object.__setattr__(self, "_below", {k: tuple(v) for k, v in below.items()})

    @property
    def joint_names(self) -> tuple[str, ...]:
        """The movable joints in the order of :attr:`joints` (the columns of ``q``)."""
        return tuple(j.name for j in self.joints if j.is_movable)

    @property
    def total_mass_kg(self) -> float:
        """Sum of the link masses."""
        return float(sum(i.mass_kg for i in self.inertials))

    def joint(self, name: str) -> ChainJoint:
        """The movable joint ``name``; :class:`JointMismatchError` listing the joints if absent."""
        for j in self.joints:
            if j.name == name and j.is_movable:
                return j
        raise JointMismatchError(
            f"gravity model: no movable joint {name!r}; joints: {', '.join(self.joint_names)}"
        )

    def q_vector(self, pose: Mapping[str, float]) -> FloatArray:
        """``(n,)`` positions in :attr:`joint_names` order from a name → angle mapping (absent joints at 0).

        Raises:
            JointMismatchError: ``pose`` names a joint the model lacks.
            InvalidCalibrationError: A value is not finite.
        """
        names = self.joint_names
        unknown = sorted(set(pose) - set(names))
        if unknown:
            raise JointMismatchError(
                f"gravity model: no movable joint {', '.join(unknown)}; joints: {', '.join(names)}"
            )
        q = np.array([float(pose.get(n, 0.0)) for n in names])
        if not np.all(np.isfinite(q)):
            bad = names[int(np.flatnonzero(~np.isfinite(q))[0])]
            raise InvalidCalibrationError(f"gravity model: joint {bad} is {pose[bad]}")
        return q


def _link_q(model: GravityModel, chain: SerialChain, q: FloatArray) -> FloatArray:
    idx = {n: k for k, n in enumerate(model.joint_names)}
    return q[:, [idx[n] for n in chain.joint_names]]


def gravity_torques(model: GravityModel, q_rad: ArrayLike | Mapping[str, float]) -> FloatArray:
    """Gravity torque on every movable joint at pose ``q_rad``.

    Args:
        model: The tree and its masses.
        q_rad: ``(n,)`` or ``(N, n)`` positions in :attr:`GravityModel.joint_names` order (rad or m), or a
            name → position mapping (absent joints at 0).

    Returns:
        ``(n,)`` or ``(N, n)`` torques, N·m (N for prismatic joints), positive towards +q.

    Raises:
        ShapeMismatchError: ``q_rad`` does not have one column per movable joint.
    """
    q = model.q_vector(q_rad) if isinstance(q_rad, Mapping) else np.asarray(q_rad, dtype=np.float64)
    single = q.ndim == 1
    q2 = q.reshape(1, -1) if single else q
    n = len(model.joint_names)
    if q2.ndim != 2 or q2.shape[1] != n:
        raise ShapeMismatchError(
            f"gravity torques: joint positions {q.shape}; expected (N, {n}) for {model.joint_names}"
        )
    g = np.asarray(model.gravity_m_s2, dtype=np.float64)
    com: dict[str, FloatArray] = {}
    weight: dict[str, FloatArray] = {}
    for inertial in model.inertials:
        chain = model._chains[inertial.link]
        T = (
            fk_chain(chain, _link_q(model, chain, q2))
            if chain.joints
            else np.broadcast_to(np.eye(4), (len(q2), 4, 4))
        )
        com[inertial.link] = T[:, :3, :3] @ np.asarray(inertial.com_xyz_m) + T[:, :3, 3]
        weight[inertial.link] = inertial.mass_kg * g
    out = np.zeros_like(q2)
    for k, name in enumerate(model.joint_names):
        joint = model.joint(name)
        links = model._below[name]
        if not links:
            continue
        chain = model._chains[joint.child]
        T = fk_chain(chain, _link_q(model, chain, q2))
        axis = T[:, :3, :3] @ np.asarray(joint.axis)
        if joint.type == "prismatic":
            force = sum(weight[lk] for lk in links)
            out[:, k] = axis @ force
            continue
        origin = T[:, :3, 3]
        moment = sum(np.cross(com[lk] - origin, weight[lk]) for lk in links)
        out[:, k] = np.einsum("ij,ij->i", axis, moment)
    return out[0] if single else out


@dataclass(frozen=True)
class JointGravity:
    """Gravity torque of one revolute joint while every other joint holds still: ``τ(q) = A·cos q + B·sin q``.

    Attributes:
        joint: Joint name.
        cos_nm: ``A`` (the torque at q = 0), N·m.
        sin_nm: ``B`` (the torque at q = π/2), N·m.
    """

    joint: str
    cos_nm: float
    sin_nm: float

    def __call__(self, q_rad: float) -> float:
        """The torque at ``q_rad`` (joint frame), N·m."""
        return self.cos_nm * math.cos(q_rad) + self.sin_nm * math.sin(q_rad)

    @property
    def amplitude_nm(self) -> float:
        """The largest torque over a turn, N·m."""
        return math.hypot(self.cos_nm, self.sin_nm)

    @property
    def hanging_rad(self) -> float:
        """The stable zero-torque angle (the joint hanging): ``τ = −amplitude·sin(q − hanging)``."""
        return math.atan2(self.cos_nm, -self.sin_nm)


def joint_gravity(model: GravityModel, joint: str, pose: Mapping[str, float] | None = None) -> JointGravity:
    """The gravity torque of ``joint`` as a function of its own angle, the others held at ``pose``.

    Args:
        model: The tree and its masses.
        joint: A revolute joint of the model.
        pose: Angles of the other joints (absent: 0; an entry for ``joint`` itself is ignored).

    Raises:
        JointMismatchError: ``joint`` is not a movable joint of the model, or ``pose`` names an unknown joint.
        InvalidCalibrationError: ``joint`` is prismatic.
    """
    j = model.joint(joint)
    if j.type != "revolute":
        raise InvalidCalibrationError(
            f"gravity model: joint {joint!r} is {j.type}; a joint gravity needs a revolute one"
        )
    base = dict(pose or {})
    q = np.stack([model.q_vector({**base, joint: 0.0}), model.q_vector({**base, joint: math.pi / 2})])
    k = model.joint_names.index(joint)
    tau = gravity_torques(model, q)[:, k]
    return JointGravity(joint, float(tau[0]), float(tau[1]))
