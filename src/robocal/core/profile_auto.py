"""The ``auto_calibration`` section of a robot profile: how the joints find their own hard stops.

Values only (no I/O); :mod:`robocal.formats.profiles` reads them from the profile YAML (schema version 2, see
``docs/profiles.md``) and :mod:`robocal.workflows.autocal.job` runs them. Angles are in the URDF joint frame,
degrees in the file and rad in the properties; torques in N·m at the output.

Safety rules that no file can lift: the search torque is a fraction of the motor model's rated torque
(:mod:`robocal.core.motor_models`; a profile may lower a rating, never raise it) and never above
:data:`HARD_MAX_TORQUE_FRACTION` of it; the speed is at most :data:`HARD_MAX_SPEED_DEG_S`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from .motor_models import HARD_MAX_TORQUE_FRACTION, MOTOR_MODELS, find_motor_model, motor_key
from .named import find_named

__all__ = [
    "AUTO_STOPS",
    "HARD_MAX_SPEED_DEG_S",
    "HARD_MAX_TORQUE_FRACTION",
    "NOT_SEARCHED",
    "RATED_TORQUE_NM",
    "AutoJoint",
    "AutoSection",
    "rated_torque_nm",
]

AUTO_STOPS = ("both", "lower", "upper", "none")
"""Which stops of a joint exist (and are searched): both, only one (one-sided zero from the stop angle), or none
(a full-turn joint: never moved, reported ``not_searched`` with the profile's ``reason``)."""
NOT_SEARCHED = "not_searched"
"""The outcome code of a joint without stops (``stops: none``): not a failure, nothing measured."""
HARD_MAX_SPEED_DEG_S = 30.0
"""No profile may approach a stop faster than this (at the output)."""

RATED_TORQUE_NM: dict[str, float] = {motor_key(m.name): m.rated_nm for m in MOTOR_MODELS}
"""Rated output torque of every model in :data:`robocal.core.motor_models.MOTOR_MODELS` (key: :func:`motor_key`)."""


def rated_torque_nm(model: str | None) -> float | None:
    """The rated torque of a motor model (``rs-02`` → 6.0, ``sts3215`` → 1.91), or None when unknown."""
    found = find_motor_model(model)
    return None if found is None else found.rated_nm


@dataclass(frozen=True)
class AutoJoint:
    """How one joint is auto-calibrated.

    Attributes:
        name: URDF joint name.
        stops: ``both``, ``lower`` or ``upper`` (:data:`AUTO_STOPS`).
        lower_deg: Expected lower stop angle (joint frame), or None (then the URDF limit).
        upper_deg: Expected upper stop angle, or None (then the URDF limit).
        tolerance_deg: How far a stop may lie beyond its expected angle (travel bound margin) and how far the
            span may differ from the expected span.
        rated_nm: Rated output torque of the motor (N·m).
        torque_fraction: Search torque as a fraction of ``rated_nm``.
        speed_deg_s: Approach speed.
        park_deg: Angle the joint moves to and holds once calibrated (None: the middle of its stops).
        pose: Angles other joints hold while this one is searched; only joints calibrated before it.
        reason: Why a joint with ``stops: none`` is not searched (shown with its ``not_searched`` outcome).
        motor: The motor model (a name :func:`robocal.core.motor_models.find_motor_model` knows), or None.
        alongside: An earlier joint this one is searched at the same time as (None: on its own, in order).
            The profile vouches that the two are independent (no collision, no gravity load on each other);
            the file reader checks that neither's pose depends on the other.
    """

    name: str
    stops: str
    rated_nm: float
    torque_fraction: float
    speed_deg_s: float
    tolerance_deg: float
    lower_deg: float | None = None
    upper_deg: float | None = None
    park_deg: float | None = None
    pose: tuple[tuple[str, float], ...] = ()
    reason: str = ""
    alongside: str | None = None
    motor: str | None = None

    @property
    def searched(self) -> bool:
        """Whether the joint is driven into a stop (False for ``stops: none``)."""
        return self.stops != "none"

    @property
    def torque_cap_nm(self) -> float:
        """Search torque (N·m): ``torque_fraction · rated_nm``."""
        return self.torque_fraction * self.rated_nm

    @property
    def model_rated_nm(self) -> float:
        """The motor model's own rating (N·m; the profile's ``rated_nm`` when the model is unknown)."""
        found = find_motor_model(self.motor)
        return self.rated_nm if found is None else found.rated_nm

    @property
    def cap_percent_of_model(self) -> float:
        """The torque cap as a percentage of the motor model's rating."""
        rated = self.model_rated_nm
        return 100.0 * self.torque_cap_nm / rated if rated > 0 else 0.0

    @property
    def speed_rad_s(self) -> float:
        """Approach speed (rad/s)."""
        return math.radians(self.speed_deg_s)

    def expected_rad(
        self, urdf_lower: float | None, urdf_upper: float | None
    ) -> tuple[float | None, float | None]:
        """Expected (lower, upper) stop angles in rad: the profile's, else the URDF's limits."""
        lo = math.radians(self.lower_deg) if self.lower_deg is not None else urdf_lower
        hi = math.radians(self.upper_deg) if self.upper_deg is not None else urdf_upper
        return lo, hi


@dataclass(frozen=True)
class AutoSection:
    """A profile's ``auto_calibration`` section.

    Attributes:
        joints: The joints in search order.
        max_torque_fraction: The cap for every joint (≤ :data:`HARD_MAX_TORQUE_FRACTION`).
        span_tolerance_deg: Default span plausibility tolerance.
        backoff_deg: Retreat after each contact.
        dwell_s: Stall dwell.
        second_touch: Touch each stop twice.
    """

    joints: tuple[AutoJoint, ...]
    max_torque_fraction: float = 0.3
    span_tolerance_deg: float = 10.0
    backoff_deg: float = 5.0
    dwell_s: float = 0.2
    second_touch: bool = False

    @property
    def joint_names(self) -> tuple[str, ...]:
        """Joint names in search order."""
        return tuple(j.name for j in self.joints)

    @property
    def searched_joints(self) -> tuple[AutoJoint, ...]:
        """The joints that move (``stops`` other than ``none``), in search order."""
        return tuple(j for j in self.joints if j.searched)

    def groups(self) -> tuple[tuple[AutoJoint, ...], ...]:
        """The joints in run order: each joint with the ones ``alongside`` it (searched at the same time)."""
        out: list[list[AutoJoint]] = []
        lead: dict[str, list[AutoJoint]] = {}
        for j in self.joints:
            if j.alongside is not None and j.alongside in lead:
                lead[j.alongside].append(j)
                continue
            out.append([j])
            lead[j.name] = out[-1]
        return tuple(tuple(g) for g in out)

    def joint(self, name: str) -> AutoJoint | None:
        """The entry of joint ``name`` or None."""
        return find_named(self.joints, name)
