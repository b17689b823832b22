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
import os
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from ...core.chain import SerialChain
from ...core.jointmap import RobotCalibration
from ...core.kinematic_errors import ErrorModel
from ...core.ur import JOINT_NAMES, LINK_NAMES, LinkOrigin, UrKinematics
from ...errors import JointMismatchError, UsageError
from ...fileio import atomic_write_text, check_output_path
from ...formats import write_calibration
from ...formats.ur_kinematics import kinematics_to_text

__all__ = [
    "ExportPaths",
    "Exports",
    "check_export_paths",
    "check_ur_chain",
    "identified_joint_map",
    "is_ur_chain",
    "prepare_exports",
    "ur_kinematics_from_chain",
    "write_exports",
]


@dataclass(frozen=True)
class ExportPaths:
    """Checked output paths of an identification (None: not asked for).

    Attributes:
        out: Corrected URDF.
        report: JSON report.
        joint_map_out: LeRobot export-urdf joint map with the identified offsets.
        ur_yaml: ur_description kinematics YAML.
    """

    out: Path | None
    report: Path | None
    joint_map_out: Path | None
    ur_yaml: Path | None


def check_export_paths(
    out: str | os.PathLike[str] | None,
    report: str | os.PathLike[str] | None,
    joint_map_out: str | os.PathLike[str] | None,
    ur_yaml: str | os.PathLike[str] | None,
    joint_map: RobotCalibration | None,
    ur_hash: str | None = None,
    inputs: Mapping[str, str | os.PathLike[str] | None] | None = None,
) -> ExportPaths:
    """Check the output options before anything is read or fitted.

    ``inputs`` are the command's input files by option (``{"--urdf": urdf, "--data": data}``): no output may be
    one of them.

    Raises:
        UsageError: An output in a missing folder, two outputs on one file, ``--joint-map-out`` without the
            joint map the readings went through, or ``--ur-hash`` without ``--ur-yaml``.
    """
    if ur_hash is not None and ur_yaml is None:
        raise UsageError("--ur-hash applies to --ur-yaml (the UR kinematics YAML the hash is written into)")
    paths = ExportPaths(
        check_output_path(out, "--out", inputs=inputs) if out is not None else None,
        check_output_path(report, "--report", inputs=inputs) if report is not None else None,
        check_output_path(joint_map_out, "--joint-map-out", inputs=inputs) if joint_map_out is not None else None,
        check_output_path(ur_yaml, "--ur-yaml", inputs=inputs) if ur_yaml is not None else None,
    )
    if paths.joint_map_out is not None and joint_map is None:
        raise UsageError("--joint-map-out needs the joint map the readings went through (--joint-map or --robot)")
    given = [p.resolve() for p in (paths.out, paths.report, paths.joint_map_out, paths.ur_yaml) if p is not None]
    if len(set(given)) != len(given):
        raise UsageError("--out, --report, --joint-map-out and --ur-yaml must be different files")
    return paths


@dataclass(frozen=True, eq=False)
class Exports:
    """What an identification writes besides its report, prepared before anything is written.

    Attributes:
        urdf_chain: The chain for ``--out``: zero offsets folded into the origins, or left out when a joint map
            with them is written.
        joint_map: The joint map with the identified offsets, or None.
        ur_text: The UR kinematics YAML text, or None.
        report: Report entries (``joint_map``, ``ur_yaml``) to merge into the report.
        warnings: E.g. a UR YAML written without the robot's hash.
    """

    urdf_chain: SerialChain
    joint_map: RobotCalibration | None
    ur_text: str | None
    report: dict[str, Any]
    warnings: tuple[str, ...]


def prepare_exports(
    model: ErrorModel,
    x: ArrayLike,
    paths: ExportPaths,
    *,
    joint_map: RobotCalibration | None = None,
    ur_hash: str | None = None,
) -> Exports:
    """The corrected chain, joint map and UR YAML of identified parameters ``x`` (nothing is written).

    Raises:
        JointMismatchError: A chain joint the joint map lacks, or ``--ur-yaml`` for a chain that is not UR's.
        UsageError: A malformed ``ur_hash``.
    """
    folded = model.corrected(x)[0]
    urdf_chain = folded
    rep: dict[str, Any] = {}
    warnings: list[str] = []
    new_map = None
    if paths.joint_map_out is not None:
        assert joint_map is not None
        urdf_chain = model.corrected(x, fold_offsets=False)[0]
        new_map = identified_joint_map(joint_map, model.offsets(x))
        rep["joint_map"] = {
            "file": str(paths.joint_map_out),
            "homing_offset": {
                n: float(v) for n, v in zip(new_map.joint_names, new_map.homing_offset, strict=True)
            },
            "note": "the zero offsets are in the joint map; the URDF written with it leaves them out",
        }
    ur_text = None
    if paths.ur_yaml is not None:
        if ur_hash is None:
            warnings.append(
                "--ur-yaml without --ur-hash: hash calib_0 written; the UR driver will report that it differs "
                "from the robot's own calibration (pass your robot's hash to silence it)"
            )
        ur_text = kinematics_to_text(ur_kinematics_from_chain(folded, ur_hash or "calib_0"))
        rep["ur_yaml"] = str(paths.ur_yaml)
    return Exports(urdf_chain, new_map, ur_text, rep, tuple(warnings))


def write_exports(exports: Exports, paths: ExportPaths, ids: Mapping[str, int] | None = None) -> None:
    """Write the joint map and UR YAML of ``exports`` (atomically, keeping a ``.bak``)."""
    if paths.joint_map_out is not None and exports.joint_map is not None:
        write_calibration(paths.joint_map_out, exports.joint_map, "robocal", ids=dict(ids or {}) or None)
    if paths.ur_yaml is not None and exports.ur_text is not None:
        atomic_write_text(paths.ur_yaml, exports.ur_text)


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
    check_ur_chain(chain)
    return _ur_kinematics(chain, hash_)


def check_ur_chain(chain: SerialChain) -> None:
    """Refuse a chain that is not a UR arm's (``--ur-yaml`` writes only those).

    Raises:
        JointMismatchError: Not a UR chain.
    """
    if not is_ur_chain(chain):
        raise JointMismatchError(
            f"--ur-yaml needs a UR chain ({', '.join(JOINT_NAMES)}); this one moves {', '.join(chain.joint_names)}"
        )


def _ur_kinematics(chain: SerialChain, hash_: str) -> UrKinematics:
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
