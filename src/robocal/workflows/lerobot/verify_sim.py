"""``--auto --verify`` on a simulated arm with a known drift: the one run the tests and the benchmark share.

:func:`verify_drift_run` opens a seeded simulated arm (SO-101 or Koch, physics, in-process port), stores the
arm's *true* calibration (its stops from the simulator's truth) with a drift injected into one joint's
``Homing_Offset`` (the file and the EEPROM alike, as a calibration that drifted after it was written), runs
:func:`~robocal.workflows.lerobot.verify.verify_calibration` and returns what was injected, what was measured and
whether anything was written. ``tests/health/test_verify.py`` and ``benchmarks/bench_health_verify.py`` both call it.
"""

from __future__ import annotations

import json
import math
import tempfile
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from ...core.lerobot import RobotSpec
from .auto import auto_section, calibration_from_stops
from .auto_sim import auto_gravity_model, open_auto_arm
from .verify import VerifyRequest, VerifyResult, verify_calibration

__all__ = ["DriftRun", "true_calibration", "verify_drift_run"]

COUNT_DEG = 360 / 4096


def true_calibration(spec: RobotSpec, truth: Mapping[str, Any]) -> dict[str, dict[str, int]]:
    """The simulated arm's true calibration (its stops from the simulator's truth), LeRobot's JSON fields."""
    out = {}
    for m in spec.motors:
        t = truth[m.name]
        cal = calibration_from_stops(
            spec,
            m.name,
            4096,
            t.stop_low_ticks * 2 * math.pi / 4096,
            t.stop_high_ticks * 2 * math.pi / 4096,
            full_range=m.name in spec.full_turn,
        )
        out[m.name] = {
            "id": cal.id,
            "drive_mode": cal.drive_mode,
            "homing_offset": cal.homing_offset,
            "range_min": cal.range_min,
            "range_max": cal.range_max,
        }
    return out


@dataclass(frozen=True)
class DriftRun:
    """One verify run on a simulated arm with an injected drift.

    Attributes:
        robot: The arm (``so101_follower``, ``koch_follower``).
        seed: The simulated arm's seed.
        joint: The drifted joint.
        counts: Counts added to its stored ``Homing_Offset``.
        injected_deg: The drift that makes: how much more the joint now reads at the same place, degrees.
        result: What verify measured.
        unchanged: The EEPROM, the file's bytes and the folder's contents are as they were, and every torque off.
    """

    robot: str
    seed: int
    joint: str
    counts: int
    injected_deg: float
    result: VerifyResult

    unchanged: bool

    @property
    def estimate_deg(self) -> float:
        """The drift verify measured on :attr:`joint`."""
        return next(j.drift_deg for j in self.result.joints if j.name == self.joint)

    @property
    def others_deg(self) -> float:
        """The largest |drift| verify measured on the other joints."""
        return max(abs(j.drift_deg) for j in self.result.joints if j.name != self.joint)


def verify_drift_run(robot: str, seed: int, joint: str, counts: int) -> DriftRun:
    """Verify a seeded simulated ``robot`` whose stored calibration of ``joint`` drifted by ``counts``.

    Args:
        robot: A robot with a simulated arm and an ``auto_calibration`` section.
        seed: The simulated arm's seed.
        joint: The joint whose ``Homing_Offset`` drifted.
        counts: Counts added to it (Feetech keeps the register within ±2047: the same offset modulo a turn).
    """
    from . import robot_spec

    spec, section = robot_spec(robot), auto_section(robot)
    rule = spec.vendor_spec.homing
    assert rule is not None, f"{robot}: no Homing_Offset register to drift"
    port = f"sim?seed={seed}&transport=inproc"
    with tempfile.TemporaryDirectory() as folder, open_auto_arm(spec, port, section) as arm:
        cals = true_calibration(spec, arm.sim.truth)
        h = cals[joint]["homing_offset"] + counts
        if rule.wraps_per_turn:
            h = (h + 2047) % 4096 - 2047
        cals[joint]["homing_offset"] = h
        path = Path(folder) / "follower.json"
        path.write_text(json.dumps(cals, indent=4))
        for name, c in cals.items():  # the arm holds that stored calibration in its EEPROM
            servo = arm.sim.servo(name)
            servo.set_reg("Homing_Offset", c["homing_offset"])
            servo.set_reg("Min_Position_Limit", c["range_min"])
            servo.set_reg("Max_Position_Limit", c["range_max"])
        eeprom, before = arm.sim.eeprom(), path.read_bytes()
        request = VerifyRequest(spec, section, path, gravity_model=auto_gravity_model(spec, port, section, None))
        result = verify_calibration(arm.bus, request, clock=arm.clock)
        limp = all(arm.sim.servo(n).get_reg("Torque_Enable") == 0 for n in cals)
        unchanged = (
            limp
            and arm.sim.eeprom() == eeprom
            and path.read_bytes() == before
            and sorted(p.name for p in Path(folder).iterdir()) == ["follower.json"]
        )
    injected = rule.offset_sign * counts * COUNT_DEG
    return DriftRun(robot, seed, joint, counts, injected, result, unchanged)
