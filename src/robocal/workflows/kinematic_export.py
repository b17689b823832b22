"""Exports of an identified chain besides the corrected URDF: the LeRobot URDF joint map and UR kinematics YAML.

* LeRobot (#4442): ``robocal lerobot export-urdf`` writes ``q_urdf = direction·scale·(Present_Position −
  homing_offset)`` per motor (robocal joint-map YAML). The identified zero offset ``δ`` of a joint means the true
  URDF angle is ``q_urdf + δ``; the same map with ``homing_offset − δ/(direction·scale)`` gives it directly. The
  URDF written next to such a map keeps the offsets out of its origins (they are in the map), so the two are
  used together.
* UR: ur_description's kinematics YAML (``kinematics_params_file``) holds the six joint origins
  (``shoulder`` … ``wrist_3``) in the URDF rpy convention; the identified origins, zero offsets folded in (a UR
  joint turns about its frame's z, so ``origin · Rz(δ)`` is exact), are written through
  :func:`robocal.formats.ur_kinematics.write_kinematics`.
"""

from __future__ import annotations

import math
from collections.abc import Mapping

import numpy as np

from ..core.chain import SerialChain
from ..core.jointmap import RobotCalibration
from ..core.ur import JOINT_NAMES, LINK_NAMES, LinkOrigin, UrKinematics
from ..errors import JointMismatchError, UsageError

__all__ = ["identified_joint_map", "is_ur_chain", "ur_kinematics_from_chain"]


def identified_joint_map(joint_map: RobotCalibration, offsets: Mapping[str, float]) -> RobotCalibration:
    """The joint map that adds each identified zero offset to the joint reading it gives.

    Args:
        joint_map: ``q = direction·scale·(raw − homing_offset)`` per joint (all joints of the arm).
        offsets: Identified zero offset per chain joint (rad, or m), ``q_true = q + offset``.

    Returns:
        The same map with ``homing_offset − offset/(direction·scale)`` on the offset joints; others unchanged.

    Raises:
        JointMismatchError: An offset for a joint the map does not have.
    """
    missing = [n for n in offsets if n not in joint_map]
    if missing:
        raise JointMismatchError(
            f"the joint map has no joint(s) {', '.join(missing)}; it has {', '.join(joint_map.joint_names)}"
        )
    new = {}
    for name, delta in offsets.items():
        i = joint_map.index(name)
        gain = float(joint_map.direction[i] * joint_map.scale[i])
        new[name] = float(joint_map.homing_offset[i]) - float(delta) / gain
    return joint_map.with_offsets(new)


def is_ur_chain(chain: SerialChain) -> bool:
    """True when the chain's movable joints are UR's six (``shoulder_pan_joint`` … ``wrist_3_joint``)."""
    return chain.joint_names == JOINT_NAMES


def ur_kinematics_from_chain(chain: SerialChain, hash_: str) -> UrKinematics:
    """ur_description kinematics of a corrected UR chain (its six movable joints' origins, URDF rpy).

    Args:
        chain: The corrected chain (offsets folded into the origins).
        hash_: ``calib_<uint64>`` to write (the robot's own hash keeps the driver's check quiet).

    Raises:
        JointMismatchError: Not a UR chain.
        UsageError: A malformed hash.
    """
    if not is_ur_chain(chain):
        raise JointMismatchError(
            f"--ur-yaml needs a UR chain ({', '.join(JOINT_NAMES)}); this one moves {', '.join(chain.joint_names)}"
        )
    body = hash_.removeprefix("calib_")
    if not (hash_.startswith("calib_") and body.isascii() and body.isdigit() and int(body) < 2**64):
        raise UsageError(f"--ur-hash {hash_!r}: expected calib_<unsigned 64-bit integer>")
    links = []
    for name, joint in zip(LINK_NAMES, chain.movable, strict=True):
        xyz = tuple(float(v) for v in joint.origin_xyz_m)
        rpy = tuple(float(v) for v in joint.origin_rpy_rad)
        if not all(math.isfinite(v) for v in (*xyz, *rpy)):
            raise UsageError(f"identified origin of {joint.name} is not finite")
        if not np.allclose(joint.axis, (0.0, 0.0, 1.0), atol=1e-12):
            raise JointMismatchError(f"{joint.name}: axis {joint.axis}; UR joints turn about z")
        links.append(LinkOrigin(name, (xyz[0], xyz[1], xyz[2]), (rpy[0], rpy[1], rpy[2])))
    return UrKinematics(tuple(links), hash_, "urdf")
