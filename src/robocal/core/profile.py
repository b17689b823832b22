"""Robot profiles: what a robot's own low-level code knows about its joints, as plain values.

A profile lists the joints a robot's upstream low-level code drives, **in that code's order**, with the name
the code uses, the name in the robot's URDF, the CAN bus and id, the axis direction and, for a one-sided
hard-stop procedure, which stop each joint is pushed into and the joint angle of that stop. Profiles are data
(``robocal/data/profiles/*.yaml``, read by :mod:`robocal.formats.profiles`); this module only holds the values
and the rules that need no I/O. See ``docs/profiles.md``.
"""

from __future__ import annotations

import math
from collections.abc import Iterable
from dataclasses import dataclass

import numpy as np

from ..errors import JointMismatchError
from .named import find_named
from .profile_auto import AutoSection
from .vendors import homing_vendors

__all__ = [
    "LEGACY_MODES",
    "METHODS",
    "NORM_MODES",
    "STOPS",
    "LeRobotSection",
    "ProfileJoint",
    "RobotProfile",
    "stop_angle_rad",
]

METHODS = ("one-sided", "two-sided")
"""Hard-stop procedures: one stop per joint (upstream Berkeley Lite) or both stops (robocal's bisection)."""
STOPS = ("lower", "upper")
"""Which stop a joint is pushed into: ``lower`` keeps the minimum of ``direction·raw``, ``upper`` the maximum."""
NORM_MODES = ("range_m100_100", "range_0_100", "degrees")
"""LeRobot ``MotorNormMode`` values a LeRobot arm's joint may use (``norm_mode``)."""
LEGACY_MODES = ("DEGREE", "LINEAR")
"""LeRobot's 2024 legacy ``CalibrationMode`` values (``legacy_mode``)."""
LEROBOT_KINDS = ("robots", "teleoperators")
"""Where LeRobot keeps a device's calibration: a robot (follower) or a teleoperator (leader)."""
LEROBOT_VENDORS = homing_vendors()
"""Servo vendors of LeRobot arms robocal drives (those declared with a homing rule in :mod:`.vendors`)."""


def stop_angle_rad(stop_deg: float) -> float:
    """A stop angle in degrees → rad, computed as ``numpy.deg2rad`` (as upstream does, so bit-identical)."""
    return float(np.deg2rad(np.float64(stop_deg)))


@dataclass(frozen=True)
class ProfileJoint:
    """One joint of a robot profile.

    Attributes:
        name: Joint name in the robot's URDF (calibration files are keyed by it).
        upstream_name: Name the upstream low-level code uses (equal to ``name`` when the same).
        bus: CAN bus (interface name) the upstream code opens for it, or None.
        motor_id: CAN id, or None (a Damiao motor: the id it listens on, ESC_ID).
        reply_id: The CAN id the motor's replies carry when it differs from ``motor_id`` (a Damiao motor's
            MST_ID; OpenArm joint n: 0x1n), or None.
        direction: Axis direction ±1 as the upstream code applies it (``q = direction·raw − offset``), or None.
        model: Motor model (e.g. ``rs-02``), or None.
        stop: For the one-sided procedure, the stop the joint is pushed into (``lower``/``upper``), or None.
        stop_deg: Joint angle of that stop, degrees (upstream writes them in degrees), or None.
        norm_mode: LeRobot arms: the motor's default ``MotorNormMode`` (one of :data:`NORM_MODES`), or None.
        legacy_mode: LeRobot arms: the 2024 legacy ``CalibrationMode`` (``DEGREE``/``LINEAR``), or None.
        operating_mode: LeRobot arms: the ``Operating_Mode`` LeRobot's ``configure()`` runs this motor in, when it
            is not the ``lerobot`` section's (the Koch gripper: current-based position, 5), or None.
        position_gains: LeRobot followers: the position loop's ``(P, I, D)`` that ``configure()`` writes on this
            motor, or None (the servo keeps its factory gains).
    """

    name: str
    upstream_name: str
    bus: str | None = None
    motor_id: int | None = None
    direction: int | None = None
    model: str | None = None
    stop: str | None = None
    stop_deg: float | None = None
    reply_id: int | None = None
    norm_mode: str | None = None
    legacy_mode: str | None = None
    operating_mode: int | None = None
    position_gains: tuple[int, int, int] | None = None

    @property
    def stop_rad(self) -> float | None:
        """The stop angle in rad (``numpy.deg2rad`` of :attr:`stop_deg`), or None."""
        return None if self.stop_deg is None else stop_angle_rad(self.stop_deg)


@dataclass(frozen=True)
class LeRobotSection:
    """How LeRobot drives and stores a LeRobot arm (the profile's ``lerobot:`` section, schema version 2).

    Attributes:
        device_name: LeRobot class ``name``, the folder of its calibration file (``so_follower`` since v0.4.3).
        old_device_name: That folder before LeRobot v0.4.3 (``so101_follower``).
        kind: ``robots`` (a follower) or ``teleoperators`` (a leader): the calibration sub-folder.
        vendor: ``feetech`` or ``dynamixel``.
        operating_mode: Operating_Mode LeRobot writes to every motor before calibrating.
        full_turn: Motors LeRobot does not sweep (their range is forced to one whole turn).
        inverted: Motors whose Drive_Mode LeRobot sets to 1 (Koch leader ``elbow_flex``).
        robot_types: Prefixes of LeRobot robot types (a dataset's ``robot_type``) that carry this arm, e.g.
            ``so`` and ``lekiwi``; a dataset recorded with such a type takes this arm's vendor and modes.
    """

    device_name: str
    old_device_name: str
    kind: str
    vendor: str
    operating_mode: int
    full_turn: tuple[str, ...] = ()
    inverted: tuple[str, ...] = ()
    robot_types: tuple[str, ...] = ()


@dataclass(frozen=True)
class RobotProfile:
    """A robot as its own low-level code sees it.

    Attributes:
        name: Profile name (``--robot NAME``).
        description: One line for humans.
        joints: The joints in the upstream code's order (the order of positional files).
        method: Default hard-stop procedure of ``robocal sweep`` (``one-sided`` or ``two-sided``).
        file_format: The calibration file format the upstream code reads (e.g. ``berkeley-offsets``), or None.
        actuator: Actuator family (``robstride``, ``recoil``, ...), or None.
        position_wraps: Whether the position reading wraps every motor turn (Robstride: yes; a multi-turn
            reading: no, then extremes are taken exactly as read).
        upstream: Where the facts come from (repository, commit, files), for humans.
        source: Where the profile was read from.
        lerobot: For a LeRobot arm, how LeRobot drives and stores it (:class:`LeRobotSection`), else None.
        version: Schema version of the file it was read from.
        auto: The ``auto_calibration`` section (automatic hard-stop search, schema version 2), or None.
    """

    name: str
    description: str
    joints: tuple[ProfileJoint, ...]
    method: str = "two-sided"
    file_format: str | None = None
    actuator: str | None = None
    position_wraps: bool = True
    upstream: str = ""
    source: str = "<memory>"
    lerobot: LeRobotSection | None = None
    version: int = 1
    auto: AutoSection | None = None

    @property
    def joint_names(self) -> tuple[str, ...]:
        """URDF joint names in the upstream order."""
        return tuple(j.name for j in self.joints)

    @property
    def upstream_names(self) -> tuple[str, ...]:
        """Upstream joint names in the upstream order."""
        return tuple(j.upstream_name for j in self.joints)

    def __contains__(self, name: object) -> bool:
        return any(j.name == name for j in self.joints)

    def joint(self, name: str) -> ProfileJoint:
        """The joint with URDF name (or upstream name) ``name``; :class:`JointMismatchError` if absent."""
        for j in self.joints:
            if name in (j.name, j.upstream_name):
                return j
        raise JointMismatchError(
            f"profile {self.name}: no joint {name!r}; joints: {', '.join(self.joint_names)}"
        )

    def get(self, name: str) -> ProfileJoint | None:
        """The joint with URDF name ``name``, or None."""
        return find_named(self.joints, name)

    def direction(self, name: str) -> int | None:
        """The profile's direction of joint ``name`` (None when the profile has no such joint or value)."""
        j = self.get(name)
        return None if j is None else j.direction

    def motor_id(self, name: str) -> int | None:
        """The profile's CAN id of joint ``name`` (None when absent)."""
        j = self.get(name)
        return None if j is None else j.motor_id

    def to_urdf_names(self, names: Iterable[str]) -> tuple[str, ...]:
        """Map upstream names (or URDF names) to URDF names; unknown names raise :class:`JointMismatchError`."""
        return tuple(self.joint(n).name for n in names)

    def matches(self, joint_names: Iterable[str]) -> bool:
        """Whether every profile joint is among ``joint_names`` (a URDF's joints)."""
        have = set(joint_names)
        return bool(self.joints) and all(j.name in have for j in self.joints)

    def one_sided_ready(self) -> tuple[str, ...]:
        """Joints lacking a stop or stop angle for the one-sided procedure (empty when all have both)."""
        return tuple(
            j.name
            for j in self.joints
            if j.stop not in STOPS or j.stop_deg is None or not math.isfinite(j.stop_deg)
        )
