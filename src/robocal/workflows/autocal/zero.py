"""Store each calibrated joint's zero in its motor (``sweep --auto --write-zero``; Damiao: 0xFE into flash).

Where a stack reads a motor's angle against the zero kept in the motor (LeRobot's ``DamiaoMotorsBus``,
openarm_can, openarm_ros2), the calibration is that zero: every joint is moved to its 0 (``s = offset``, from its
stops), held and refined until the reading agrees within :data:`ZERO_TOL_RAD`, and then the driver stores its
present position as the motor's zero (:meth:`DamiaoJointDriver.store_zero`: limp, disable, 0xFE, disable). The
joints are all moved first (each holds while the next moves), then zeroed one by one in the profile's order; a
zeroed motor is limp, and at the joints' 0 (the arm hanging, elbow and gripper on their stops) gravity pulls no
joint away. Runs inside the caller's motion guard.
"""

from __future__ import annotations

import logging
import math
from collections.abc import Callable, Mapping, Sequence

import numpy as np

from ...backends.bus_transaction import holding
from ...core.profile_auto import AutoSection
from ...core.stop_search import Command
from ...core.sweep import analyse_sweep
from ...core.sweep_result import SweepResult
from ...errors import DeviceError, UsageError
from .joint import TRANSIT_FACTOR, move_to
from .model import JointDriver, limp_all

__all__ = ["HOLD_S", "ZERO_TOL_RAD", "can_store_zero", "rezeroed_result", "store_zeros", "zeros_written"]

ZERO_TOL_RAD = math.radians(0.02)
"""The held joint's angle must be within this of 0 before its zero is stored (up to 8 refinements)."""
HOLD_S = 0.3
"""How long a joint is held (and read) at each refinement."""


def can_store_zero(drivers: Mapping[str, JointDriver], names: Sequence[str]) -> None:
    """Refuse, before anything moves, joints whose driver cannot store a zero in its motor.

    Raises:
        UsageError: Naming them.
    """
    lacking = [n for n in names if not hasattr(drivers.get(n), "store_zero")]
    if lacking:
        raise UsageError(
            f"--write-zero: the motors of {', '.join(lacking)} keep no zero robocal can store (a Damiao motor does)"
        )


def _hold(driver: JointDriver, name: str, target: float, cap: float, periods: int) -> float:
    """Hold ``name`` at ``target`` (rad) for ``periods``; the mean reading of the second half (rad).

    Raises:
        DeviceError: No reading came in the second half (the motor stopped answering): there is no position to
            refine the target with, nor one to store as its zero.
    """
    settle = getattr(driver, "settle_at", None)
    if settle is not None:
        q = float(settle(target, periods * 0.01))
    else:
        qs = [driver.execute(Command("drive", target, 0.0, cap)).q_rad for _ in range(periods)]
        half = [q for q in qs[len(qs) // 2 :] if math.isfinite(q)]
        q = float(np.mean(half)) if half else math.nan
    if not math.isfinite(q):
        raise DeviceError(f"{name}: no position reading while holding it at its zero (the motor stopped answering)")
    return q


def _tell(driver: JointDriver, name: str, state: str, s_rad: float = 0.0) -> None:
    """Tell the driver's ``on_zero`` hook (the state folder's record) a zero's state and the motor's reading there."""
    hook = getattr(driver, "on_zero", None)
    if hook is not None:
        hook(name, state, getattr(driver, "direction", 1) * s_rad)


def _say_left(stored: Sequence[str], failed: str) -> None:
    """A fault while zeros go to flash: one ``note:`` on what is in flash (no write takes it back), no file."""
    what = f"the zero{'s' if len(stored) > 1 else ''} of {', '.join(stored)} {'are' if len(stored) > 1 else 'is'} in flash, " if stored else ""
    logging.getLogger("robocal.notes").warning(
        "%s%s's may be (its store failed); no calibration file was written: run `robocal sweep --auto "
        "--write-zero` again to write it",
        what,
        failed,
    )


def zeros_written(drivers: Mapping[str, JointDriver], names: Sequence[str]) -> None:
    """The calibration file holding these joints' new zeros is written: the record of them can go."""
    for name in names:
        _tell(drivers[name], name, "written")


def store_zeros(
    drivers: Mapping[str, JointDriver],
    offsets_rad: Mapping[str, float],
    section: AutoSection,
    *,
    max_lag_rad: float,
    period_s: float = 0.01,
    before_store: Callable[[], object] | None = None,
) -> dict[str, float]:
    """Move every joint of ``offsets_rad`` to its 0, then store each one's zero in its motor.

    ``before_store`` is called once, after the moves and before the first zero is stored (the caller holds
    signals back from there until its file is written: a flash write cannot be taken back). A signal held back
    meanwhile stores no further zero: the joints not yet zeroed are made limp at once (issue 26: within 100 ms,
    not after the other motors' flash writes) and left with their zero as it was; the caller's file says which
    zeros were stored.

    Each driver's ``on_zero`` hook, where it has one, is told each zero's state (``planned`` for all before the
    first flash write, then ``storing`` and ``stored`` around each; ``unchanged`` for those a signal spared), with
    the motor's reading where the zero goes; the caller tells it ``written`` (:func:`zeros_written`) once its
    file holds them.

    Returns:
        Joint → its angle (from its stops) where the zero was stored, rad: the new zero's error (only the joints
        whose zero was stored).
    """
    at: dict[str, float] = {}
    # in the profile's order, whatever the caller's: the joints already moved load the next one (a shoulder's
    # deflection at its zero depends on where the elbow is), so another order stores other zeros
    for name in [n for n in section.joint_names if n in offsets_rad]:
        offset = offsets_rad[name]
        aj = section.joint(name)
        assert aj is not None
        d = drivers[name]
        move_to(d, offset, aj.speed_rad_s * TRANSIT_FACTOR, aj.torque_cap_nm, max_lag_rad)
        target = offset
        q = _hold(d, name, target, aj.torque_cap_nm, round(HOLD_S / period_s))
        for _ in range(8):
            if abs(q - offset) <= ZERO_TOL_RAD:
                break
            target -= q - offset
            q = _hold(d, name, target, aj.torque_cap_nm, round(HOLD_S / period_s))
        at[name] = q - offset
    zeroing = [n for n in section.joint_names if n in at]
    for name in zeroing:  # recorded before the first flash write: a killed run's next run says what it left
        _tell(drivers[name], name, "planned", offsets_rad[name] + at[name])
    if before_store is not None:
        before_store()
    stored: dict[str, float] = {}
    for name in zeroing:
        if holding():  # a signal came: no further flash write; every joint still held goes limp now
            limp_all([drivers[n] for n in at if n not in stored])
            break
        q_zero = offsets_rad[name] + at[name]
        _tell(drivers[name], name, "storing", q_zero)
        try:
            drivers[name].store_zero()  # type: ignore[attr-defined]
        except Exception:
            _say_left(list(stored), name)
            raise
        stored[name] = at[name]
        _tell(drivers[name], name, "stored", q_zero)
    for name in zeroing:
        if name not in stored:
            _tell(drivers[name], name, "unchanged")
    return stored


def rezeroed_result(
    result: SweepResult, q_at_zero: Mapping[str, float], *, wraps: bool = True, zero_sta: int = 0
) -> SweepResult:
    """The sweep result in the motors' new frame: each stored joint's offset is ``−direction·q_at_zero``.

    The extremes move with the zero and every diagnostic is computed again for the new offsets (a hint about a
    large factory offset, or a power-on wrap inside the old travel, no longer applies).
    """
    smin, smax = [], []
    for j in result.joints:
        shift = 0.0
        if j.name in q_at_zero:
            h_new = -j.direction * q_at_zero[j.name]
            shift = j.direction * (j.homing_offset - h_new)  # identity-frame readings move by this
        smin.append(j.sampled_min - shift)
        smax.append(j.sampled_max - shift)
    prior = {j.name: j.previous_homing_offset for j in result.joints if j.previous_homing_offset is not None}
    return analyse_sweep(
        [j.name for j in result.joints],
        [j.direction for j in result.joints],
        [j.lower for j in result.joints],
        [j.upper for j in result.joints],
        smin,
        smax,
        prior=prior,
        threshold_rad=0.0,
        span_tolerance_rad=result.span_tolerance_rad,
        wraps=wraps,
        zero_sta=zero_sta,
    )
