"""The two LeRobot calibration files of a simulated teleoperation session, made the way a real offset is made.

In LeRobot's DEGREES mode a value is ``(present − mid)·360/4095`` with ``mid`` the middle of the range the
operator recorded (``range_min``, ``range_max``); the homing pose does not enter it. A degree-mode zero is wrong
when the recorded range is not the joint's stops: an operator who stops ``s_lo`` short of the lower stop and
``s_hi`` short of the upper one makes the arm read ``e = (s_hi − s_lo)/2`` more than its true angle (the angle
about the middle of its stops). A 17° offset is a range recorded 34° short at one end.

:func:`calibration_pair` writes that cause for the session's injected offset: on the arm and joint whose
calibration is off, the end that makes its sign recorded ``2·|e|`` short; every joint with stops on both arms also
stops short of both ends by the same hand scatter ``x`` (uniform 0–1.5°, the same at both ends, so it adds no
offset and the session's truth stays exact). LeRobot's full-turn motors (the SO-101's ``wrist_roll``, the Koch's
``shoulder_pan`` and ``wrist_roll``) record the whole turn (``0..4095``): their offset, a homing difference, is
not in the files. Grippers (``range_0_100``) record the profile's stops, which is what the dataset's values
assume.

Only this mechanism is simulated. Two arms whose mechanical stops differ, or a leader whose range was recorded
correctly but whose horn slipped later, have offsets the files cannot show.
"""

from __future__ import annotations

from pathlib import Path

from ..backends.sim.teleop import SCATTER_DEG, TELEOP_ARMS, TeleopSession
from ..core.arrays import FloatArray
from ..core.lerobot.calibration import MotorCalibration
from ..formats.lerobot import write_current

__all__ = ["FULL_TURN", "SCATTER_DEG", "calibration_pair", "write_calibration_pair"]

FULL_TURN: dict[str, tuple[str, ...]] = {name: arm.full_turn for name, arm in TELEOP_ARMS.items()}
"""LeRobot's full-turn motors per simulated pair (recorded ``0..4095``)."""

_TICKS_PER_DEG = 4095 / 360
"""LeRobot's DEGREES scale (``resolution − 1`` ticks per turn)."""
_MIDDLE = 2047
"""Where the middle of the range reads (LeRobot homes the middle pose to half a turn)."""


def _arm_files(
    session: TeleopSession, arm_offsets: dict[str, float], scatter_deg: FloatArray
) -> dict[str, MotorCalibration]:
    arm = session.arm
    out: dict[str, MotorCalibration] = {}
    for k, name in enumerate(arm.joints):
        lo, hi = arm.stop_lo_deg[k], arm.stop_hi_deg[k]
        if not arm.recorded(k):
            out[name] = MotorCalibration(k + 1, 0, 0, 0, 4095)
            continue
        if arm.modes[k] != "degrees":  # the gripper: its values assume the profile's stops
            out[name] = MotorCalibration(
                k + 1, 0, 0, round(_MIDDLE + lo * _TICKS_PER_DEG), round(_MIDDLE + hi * _TICKS_PER_DEG)
            )
            continue
        e = arm_offsets.get(name, 0.0)
        x = float(scatter_deg[k])
        s_lo = x + (2.0 * -e if e < 0 else 0.0)
        s_hi = x + (2.0 * e if e > 0 else 0.0)
        # present = middle + (true + e)·ticks/deg, the dataset's value (the simulated stops are symmetric about
        # 0): the recorded ends are the true angles lo + s_lo and hi − s_hi, their middle reads `middle`
        r_min = round(_MIDDLE + (lo + s_lo + e) * _TICKS_PER_DEG)
        r_max = round(_MIDDLE + (hi - s_hi + e) * _TICKS_PER_DEG)
        out[name] = MotorCalibration(k + 1, 0, 0, r_min, r_max)
    return out


def calibration_pair(session: TeleopSession) -> tuple[dict[str, MotorCalibration], dict[str, MotorCalibration]]:
    """The leader's and the follower's LeRobot calibrations that produce the session's injected offset.

    The hand scatter is the session's (:meth:`~robocal.backends.sim.teleop.TeleopSession.scatter`): the follower's
    file holds the position limits its simulated servo enforced.

    Args:
        session: A simulated session (its ``faults.offset_*`` say which arm and joint is off, and by how much).

    Returns:
        ``(leader, follower)``: motor → calibration (Feetech / Dynamixel alike: homing 0, drive mode 0).
    """
    f = session.faults
    lead: dict[str, float] = {}
    foll: dict[str, float] = {}
    if f.offset_joint is not None:
        (lead if f.offset_arm == "leader" else foll)[f.offset_joint] = f.offset_deg
    x_lead, x_foll = session.scatter()
    return _arm_files(session, lead, x_lead), _arm_files(session, foll, x_foll)


def write_calibration_pair(session: TeleopSession, root: str | Path) -> tuple[Path, Path]:
    """Write ``ROOT.leader.json`` and ``ROOT.follower.json`` (LeRobot's current format) beside a dataset root.

    The scatter is seeded from the session's seed, so a root's files are the same on every run.
    """
    r = Path(root)
    leader, follower = calibration_pair(session)
    paths = (r.with_name(r.name + ".leader.json"), r.with_name(r.name + ".follower.json"))
    write_current(paths[0], leader)
    write_current(paths[1], follower)
    return paths
