"""The power-on branch check behind ``robocal check --source``.

The first reading after power-on of each joint, with the 2π branch selection that puts it inside its URDF limits.
"""

from __future__ import annotations

import math
import os
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ...backends.sources import DEFAULT_TOPIC, Source, open_source
from ...core.profile import RobotProfile
from ...errors import FileFormatError, JointMismatchError
from .joint_specs import joint_calibration, read_joints
from .session import check_source_options

__all__ = ["BranchCheck", "check_source", "check_source_options"]


@dataclass(frozen=True)
class BranchCheck:
    """First reading after power-on of one joint, with the 2π branch selection applied.

    Attributes:
        name: Joint name.
        raw_rad: Raw motor position as read, rad.
        raw_selected_rad: Raw position on the branch that puts the joint inside its limits, rad.
        turns: Whole turns added (``(raw_selected − raw)/2π``).
        q_rad: Joint position on the selected branch, rad.
        lower: Lower limit, rad.
        upper: Upper limit, rad.
        in_limits: Whether ``q_rad`` is inside the limits (± margin).
    """

    name: str
    raw_rad: float
    raw_selected_rad: float
    turns: int
    q_rad: float
    lower: float
    upper: float
    in_limits: bool

    @property
    def problem(self) -> str | None:
        """A one-line problem description, or None."""
        if not self.in_limits:
            return (
                f"{self.name}: q = {self.q_rad:.3f} rad is outside [{self.lower:.3f}, {self.upper:.3f}] "
                "on every 2π branch; recalibrate or check the URDF"
            )
        return None


def check_source(
    urdf_path: str | Path,
    calibration_path: str | Path,
    source: str,
    *,
    topic: str = DEFAULT_TOPIC,
    frame: str | None = None,
    margin_rad: float = 0.05,
    open_source_fn: Callable[..., Source] | None = None,
    robot: str | os.PathLike[str] | RobotProfile | None = None,
) -> list[BranchCheck]:
    """Read the first sample after power-on and apply the 2π branch selection per joint.

    Args:
        urdf_path: The URDF.
        calibration_path: The calibration file (any format robocal reads).
        source: ``--source``.
        topic: rosbag2 topic.
        frame: Replay frame.
        margin_rad: Tolerance on the limits, rad.
        open_source_fn: Opens the source.
        robot: Robot profile (default: the built-in robot the URDF's joint names match).

    Returns:
        One :class:`BranchCheck` per URDF joint the calibration has, in URDF order (``robocal check`` reports
        the joints it lacks).
    """
    spec = check_source_options(source, frame)
    all_joints, cf = read_joints(urdf_path, calibration_path, robot)
    keep = [i for i, j in enumerate(all_joints) if j.name in cf.calibration]
    if not keep:
        raise JointMismatchError(f"calibration {calibration_path}: no offset for any joint of the URDF")
    joints = [all_joints[i] for i in keep]
    names = [j.name for j in joints]
    cal = joint_calibration(cf, joints)
    src = (open_source_fn or open_source)(spec, all_joints, topic=topic, frame=frame)
    try:
        sample = src.read()
        if sample is None:
            raise FileFormatError(f"source {source}: no samples")
        d = np.array([j.direction for j in joints], dtype=np.float64)
        pos = sample.position_rad[keep]
        raw = pos if src.frame == "motor" else d * pos  # identity → raw is d·s as well (d² = 1)
    finally:
        src.close()
    if not np.all(np.isfinite(raw)):
        bad = [n for n, r in zip(names, raw, strict=True) if not math.isfinite(r)]
        raise FileFormatError(f"source {source}: first sample has no position for {', '.join(bad)}")
    lo = np.array([j.lower for j in joints])
    up = np.array([j.upper for j in joints])
    sel = cal.unwrap_to_limits(raw, lo, up)
    q = cal.to_joint(sel)
    inside = (q >= lo - margin_rad) & (q <= up + margin_rad)
    return [
        BranchCheck(
            n,
            float(raw[i]),
            float(sel[i]),
            round((sel[i] - raw[i]) / (2 * math.pi)),
            float(q[i]),
            float(lo[i]),
            float(up[i]),
            bool(inside[i]),
        )
        for i, n in enumerate(names)
    ]
