"""A LeRobot arm as its calibration sees it, built from its robot profile (``docs/profiles.md``)."""

from __future__ import annotations

from dataclasses import dataclass

from ...errors import UsageError
from ..profile import RobotProfile
from ..vendors import HomingRule, VendorSpec, vendor_spec

__all__ = ["LeRobotMotor", "RobotSpec"]


@dataclass(frozen=True)
class LeRobotMotor:
    """One motor of a LeRobot arm: name, bus id, model, LeRobot norm mode and legacy calibration mode.

    ``operating_mode`` is the mode LeRobot runs it in when that is not the arm's (None: the arm's);
    ``position_gains`` the ``(P, I, D)`` LeRobot's follower writes on it (None: the servo's factory gains).
    """

    name: str
    motor_id: int
    model: str
    norm_mode: str
    legacy_mode: str = "DEGREE"
    operating_mode: int | None = None
    position_gains: tuple[int, int, int] | None = None


@dataclass(frozen=True)
class RobotSpec:
    """A LeRobot arm as its calibration sees it (built from its robot profile by :meth:`from_profile`).

    Attributes:
        name: robocal / LeRobot CLI name (``"so101_follower"``).
        device_name: LeRobot class ``name`` used in the calibration path (``"so_follower"`` since v0.4.3).
        old_device_name: The directory name before v0.4.3 (``"so101_follower"``).
        kind: ``"robots"`` or ``"teleoperators"``.
        vendor: ``"feetech"`` or ``"dynamixel"``.
        motors: Motors in bus order.
        full_turn: Motors LeRobot does not sweep (forced to ``0..resolution − 1``).
        operating_mode: Operating_Mode written before calibrating.
        inverted: Motors whose drive_mode is 1 (Koch leader ``elbow_flex``).
    """

    name: str
    device_name: str
    old_device_name: str
    kind: str
    vendor: str
    motors: tuple[LeRobotMotor, ...]
    full_turn: tuple[str, ...]
    operating_mode: int
    inverted: tuple[str, ...] = ()

    @property
    def vendor_spec(self) -> VendorSpec:
        """The declaration of its vendor (:mod:`robocal.core.vendors`): every vendor-dependent rule.

        Raises:
            UsageError: No vendor is declared under its name.
        """
        return vendor_spec(self.vendor)

    @property
    def homing(self) -> HomingRule:
        """Its vendor's homing rule (sign and encoding of ``Homing_Offset``)."""
        return self.vendor_spec.homing_rule()

    def run_mode(self, motor: LeRobotMotor) -> int:
        """The ``Operating_Mode`` LeRobot runs ``motor`` in (after ``configure()``)."""
        return self.operating_mode if motor.operating_mode is None else motor.operating_mode

    @property
    def motor_names(self) -> tuple[str, ...]:
        """Motor names in bus order."""
        return tuple(m.name for m in self.motors)

    @classmethod
    def from_profile(cls, profile: RobotProfile) -> RobotSpec:
        """The LeRobot arm of a robot profile with a ``lerobot`` section (see ``docs/profiles.md``).

        Raises:
            UsageError: The profile is not a LeRobot arm (no ``lerobot`` section).
        """
        lr = profile.lerobot
        if lr is None:
            raise UsageError(f"robot profile {profile.name} is not a LeRobot arm (it has no lerobot section)")
        motors = []
        for j in profile.joints:
            if (
                j.motor_id is None or j.model is None or j.norm_mode is None
            ):  # pragma: no cover - parser checks
                raise UsageError(f"robot profile {profile.name}: joint {j.name} lacks id, model or norm_mode")
            motors.append(
                LeRobotMotor(
                    j.name,
                    j.motor_id,
                    j.model,
                    j.norm_mode,
                    j.legacy_mode or "DEGREE",
                    j.operating_mode,
                    j.position_gains,
                )
            )
        return cls(
            profile.name,
            lr.device_name,
            lr.old_device_name,
            lr.kind,
            lr.vendor,
            tuple(motors),
            lr.full_turn,
            lr.operating_mode,
            lr.inverted,
        )
