"""How a dataset's stored joint values relate to the motors' actual encoder positions.

Re-calibrating a dataset is ``value_old → actual → value_new``: every convention maps stored values to the
motor's *actual* encoder position (the position the encoder reports with no homing offset applied, in raw
units: ticks for servos, rad for Robstride) and back. The actual position is the one quantity both the old and
the new calibration agree on, because it does not depend on any calibration.

Implementations: :class:`JointMapConvention` (robocal's canonical joint map, joint-frame radians) and, in
:mod:`robocal.dataset.lerobot`, LeRobot's current and legacy conventions.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Protocol, TypeAlias, runtime_checkable

import numpy as np

from ..core.arrays import BoolArray, FloatArray
from ..core.jointmap import RobotCalibration
from ..errors import InvalidCalibrationError, JointMismatchError

__all__ = ["Conventions", "FloatArray", "JointMapConvention", "ValueConvention", "check_joint_names", "select_indices"]



@runtime_checkable
class ValueConvention(Protocol):
    """A per-joint map between stored values and actual encoder positions.

    Implementations are frozen, picklable values (they are sent to worker processes).
    """

    @property
    def joint_names(self) -> tuple[str, ...]:
        """Joint names in the order of the value arrays' last axis."""
        ...

    def select(self, joint_names: Sequence[str]) -> ValueConvention:
        """The same convention restricted to and reordered as ``joint_names``."""
        ...

    def to_actual(self, values: FloatArray) -> FloatArray:
        """Stored values, shape ``(N, D)`` → actual encoder positions, shape ``(N, D)``, raw units."""
        ...

    def from_actual(self, actual: FloatArray) -> tuple[FloatArray, BoolArray]:
        """Actual encoder positions ``(N, D)`` → (stored values ``(N, D)``, out-of-range mask ``(N, D)``).

        The mask is ``True`` where the position lies outside the range this calibration covers (where
        LeRobot's range modes clamp); those values are still mapped (clamped or not, as the convention does)
        and counted.
        """
        ...

    def value_range(self) -> tuple[FloatArray, FloatArray] | None:
        """Calibrated range per joint in stored-value units, ``(lo (D,), hi (D,))``; ``None``: unbounded."""
        ...

    def full_turn(self) -> FloatArray:
        """Change of the stored value per full encoder turn, shape ``(D,)`` (absolute value)."""
        ...


Conventions: TypeAlias = "ValueConvention | Mapping[str, ValueConvention]"
"""One convention for every feature, or one per feature key."""


def select_indices(wanted: Sequence[str], available: Sequence[str], owner: str, noun: str) -> list[int]:
    """Where each of ``wanted`` is in ``available``, for a convention's ``select``.

    Raises:
        JointMismatchError: ``"<owner>: no <noun> named <the missing ones>"``.
    """
    first: dict[str, int] = {}
    for i, name in enumerate(available):
        first.setdefault(name, i)
    missing = [n for n in wanted if n not in first]
    if missing:
        raise JointMismatchError(f"{owner}: no {noun} named {', '.join(missing)}")
    return [first[n] for n in wanted]


def check_joint_names(expected: Sequence[str], available: Sequence[str], where: str) -> None:
    """Raise :class:`JointMismatchError` unless ``expected`` and ``available`` name the same joints.

    Args:
        expected: Joint names the dataset feature holds.
        available: Joint names the calibration holds.
        where: What is being matched, used in the message (``"feature 'action' vs --old"``).
    """
    missing = [n for n in expected if n not in available]
    extra = [n for n in available if n not in expected]
    dup = sorted({n for n in expected if list(expected).count(n) > 1})
    if missing or extra or dup:
        parts = []
        if missing:
            parts.append(f"not in the calibration: {', '.join(missing)}")
        if extra:
            parts.append(f"not in the dataset: {', '.join(extra)}")
        if dup:
            parts.append(f"duplicated: {', '.join(dup)}")
        raise JointMismatchError(f"{where}: joint names do not match ({'; '.join(parts)})")


@dataclass(frozen=True, eq=False)
class JointMapConvention:
    """Stored values are joint-frame positions of robocal's canonical joint map.

    ``q = direction·scale·(actual − homing_offset)``, so ``actual = direction·q/scale + homing_offset``.

    Attributes:
        calibration: The robot's canonical calibration (joint names, directions, offsets, scales).
        lower: Optional lower joint limits, shape ``(D,)``, joint units; values below are counted.
        upper: Optional upper joint limits, shape ``(D,)``, joint units; values above are counted.
        turn_raw: Encoder period in raw units (2π for Robstride, 4096 for a 4096-tick servo); ``None``: one
            encoder turn is one joint turn (2π rad), true for direct-drive servos and Robstride joints.
    """

    calibration: RobotCalibration
    lower: FloatArray | None = None
    upper: FloatArray | None = None
    turn_raw: float | None = None

    def __post_init__(self) -> None:
        n = self.calibration.n_joints
        for name in ("lower", "upper"):
            arr = getattr(self, name)
            if arr is not None:
                a = np.asarray(arr, dtype=np.float64)
                if a.shape != (n,) or np.any(np.isnan(a)):
                    raise InvalidCalibrationError(f"joint limits {name}: {n} numbers expected, no NaN")
                object.__setattr__(self, name, a)

    @property
    def joint_names(self) -> tuple[str, ...]:
        """Joint names in column order."""
        return self.calibration.joint_names

    def select(self, joint_names: Sequence[str]) -> JointMapConvention:
        """Restrict to and reorder as ``joint_names``."""
        idx = select_indices(joint_names, self.joint_names, "joint map", "joint")
        return JointMapConvention(
            calibration=self.calibration.select(joint_names),
            lower=None if self.lower is None else self.lower[idx],
            upper=None if self.upper is None else self.upper[idx],
            turn_raw=self.turn_raw,
        )

    def to_actual(self, values: FloatArray) -> FloatArray:
        """Joint positions ``(N, D)`` → actual raw positions ``(N, D)``."""
        return self.calibration.to_raw(values)

    def from_actual(self, actual: FloatArray) -> tuple[FloatArray, BoolArray]:
        """Actual raw positions ``(N, D)`` → joint positions and the outside-the-limits mask."""
        q = self.calibration.to_joint(actual)
        mask = np.zeros(q.shape, dtype=np.bool_)
        if self.lower is not None:
            mask |= q < self.lower
        if self.upper is not None:
            mask |= q > self.upper
        return q, mask

    def value_range(self) -> tuple[FloatArray, FloatArray] | None:
        """The joint limits, if given."""
        if self.lower is None or self.upper is None:
            return None
        return self.lower, self.upper

    def full_turn(self) -> FloatArray:
        """One encoder turn in joint units: ``|scale|·turn_raw`` per joint (2π rad without ``turn_raw``)."""
        if self.turn_raw is None:
            return np.full(self.calibration.n_joints, 2.0 * np.pi)
        out: FloatArray = np.abs(self.calibration.scale) * self.turn_raw
        return out
