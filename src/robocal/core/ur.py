"""Universal Robots kinematics: models, the corrected kinematics file content, URDF-style FK (pure numpy).

The controller reports calibrated DH parameters; :mod:`robocal.core.ur_correction` moves the ``d`` of joints 2
and 3 onto the next joint (the ``ur_calibration`` algorithm) so that six joint-origin transforms describe the
physical arm. This module names the models and their nominal DH, turns the six transforms into the
ur_description kinematics content (:class:`UrKinematics`, rpy in the URDF or upstream convention, the
``calib_`` hash) and evaluates that content the way a URDF does, through :func:`robocal.core.chain.fk_chain`,
so that verification compares the DH forward kinematics with an independent URDF-chain FK.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import lru_cache

import numpy as np
from numpy.typing import ArrayLike

from ..errors import ShapeMismatchError, UsageError
from .arrays import FloatArray
from .chain import ChainJoint, SerialChain, fk_chain
from .dh import DHParameters
from .se3 import eigen_euler_xyz, rot_z, rpy_urdf_from_matrix, transform_from_xyz_rpy_urdf
from .ur_correction import MIN_ABS_COS_ALPHA, correct_chain, six_transforms, split_chain
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


@lru_cache(maxsize=8)
def _revolute_z_chain(n: int) -> SerialChain:
    """``n`` revolute joints about their z axis in series (their origins are given per call)."""
    z = (0.0, 0.0, 1.0)
    joints = tuple(ChainJoint(f"joint_{k + 1}", "revolute", f"link_{k}", f"link_{k + 1}", axis=z) for k in range(n))
    return SerialChain(joints, "link_0", f"link_{n}")


def fk_origins(xyz_m: ArrayLike, rpy_rad: ArrayLike, q_rad: ArrayLike) -> FloatArray:
    """Forward kinematics the way a URDF evaluates six revolute joints with ``<axis xyz="0 0 1"/>``.

    ``T = Π_k T(xyz_k) · Rz(yaw_k)Ry(pitch_k)Rx(roll_k) · Rz(q_k)`` (URDF rpy semantics), evaluated by
    :func:`robocal.core.chain.fk_chain`, the one URDF-chain FK.

    Args:
        xyz_m: ``(6, 3)`` origins, metres.
        rpy_rad: ``(6, 3)`` URDF rpy, radians.
        q_rad: ``(6,)`` or ``(N, 6)`` joint positions, radians.

    Returns:
        ``(4, 4)`` or ``(N, 4, 4)`` base → flange transforms.
    """
    q = np.asarray(q_rad, dtype=np.float64)
    origins = transform_from_xyz_rpy_urdf(np.asarray(xyz_m), np.asarray(rpy_rad))
    if q.ndim not in (1, 2) or origins.ndim != 3 or origins.shape[0] != q.shape[-1]:
        raise ShapeMismatchError(f"fk_origins: {origins.shape[0]} origins but joint vectors {q.shape}")
    return fk_chain(_revolute_z_chain(int(origins.shape[0])), q, origins=list(origins))


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
