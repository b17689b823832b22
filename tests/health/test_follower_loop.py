"""The follower's position loop as the dataset health check models it: stiffness from the vendor's loop model at
the gains LeRobot writes (the profile's ``position_gains``) or the factory's, and goal limits by the mode LeRobot
runs each motor in (the vendor's ``goal_limit_modes``), not by the servo model."""

from __future__ import annotations

import math
from importlib import resources
from pathlib import Path

import pytest
import yaml

from robocal.backends.sim.teleop import TELEOP_ARMS
from robocal.core.lerobot import RobotSpec
from robocal.formats.profiles import load_profile
from robocal.workflows.dataset.health import follower_loop

ARM = ("shoulder_pan", "shoulder_lift", "elbow_flex", "wrist_flex", "wrist_roll", "gripper")


def _loop(robot: str) -> tuple[dict[str, float], dict[str, bool], dict[str, float]]:
    return follower_loop(RobotSpec.from_profile(load_profile(robot)))


def test_so101_follower_is_stiff_as_lerobot_sets_it_and_clamped_to_its_limits() -> None:
    kp, limited, _ = _loop("so101_follower")
    # P_Coefficient 16 on a 1.91 N·m STS3215: 16/1024 · 1.91 N·m per tick · 4096/2π ticks per rad
    assert kp == pytest.approx(dict.fromkeys(ARM, 16 / 1024 * 1.91 * 4096 / math.tau), rel=1e-3)
    assert kp["elbow_flex"] == pytest.approx(19.455, abs=1e-3)
    assert limited == {**dict.fromkeys(ARM, True), "wrist_roll": False}  # the full-turn motor: limits 0..4095


def test_koch_follower_keeps_factory_gains_but_the_elbow_and_is_never_clamped() -> None:
    kp, limited, _ = _loop("koch_follower")
    # XL430 Position_P_Gain 640 (factory), XL330 400 (factory), the elbow 1500 (LeRobot): P/128 current units
    # per tick, 2.69 mA (XL430, 1.5 N·m / 1.4 A) or 1 mA (XL330, 0.52 N·m / 1.47 A) per unit
    assert kp["shoulder_lift"] == pytest.approx(640 / 128 * 0.00269 * 1.5 / 1.4 * 4096 / math.tau, rel=1e-3)
    assert kp["elbow_flex"] == pytest.approx(1500 / 128 * 0.001 * 0.52 / 1.47 * 4096 / math.tau, rel=2e-2)
    assert kp["wrist_flex"] == pytest.approx(kp["elbow_flex"] * 400 / 1500)
    assert limited == dict.fromkeys(ARM, False)  # extended position (4), the gripper current-based position (5)


def _profile_copy(
    tmp_path: Path, robot: str, edit: dict[str, object], joint_edit: dict[str, dict[str, object]]
) -> Path:
    text = (resources.files("robocal") / "data" / "profiles" / f"{robot}.yaml").read_text()
    doc = yaml.safe_load(text)
    doc["name"] = f"my_{robot}"
    doc["lerobot"].update(edit)
    for j in doc["joints"]:
        j.update(joint_edit.get(j["name"], {}))
    out = tmp_path / f"my_{robot}.yaml"
    out.write_text(yaml.safe_dump(doc))
    return out


def test_goal_limits_follow_the_mode_the_motor_runs_in(tmp_path: Path) -> None:
    # a Feetech arm run in step mode (3) is not clamped to its position limits
    so = _profile_copy(tmp_path, "so101_follower", {"operating_mode": 3}, {})
    assert follower_loop(RobotSpec.from_profile(load_profile(str(so))))[1] == dict.fromkeys(ARM, False)
    # a Dynamixel in position mode (3) is
    koch = _profile_copy(tmp_path, "koch_follower", {}, {"shoulder_lift": {"operating_mode": 3}})
    limited = follower_loop(RobotSpec.from_profile(load_profile(str(koch))))[1]
    assert limited == {**dict.fromkeys(ARM, False), "shoulder_lift": True}


def test_gains_a_profile_declares_are_the_ones_modelled(tmp_path: Path) -> None:
    so = _profile_copy(tmp_path, "so101_follower", {}, {"shoulder_lift": {"position_gains": [32, 0, 32]}})
    kp = follower_loop(RobotSpec.from_profile(load_profile(str(so))))[0]
    assert kp["shoulder_lift"] == pytest.approx(2 * kp["elbow_flex"])


@pytest.mark.parametrize(("arm", "robot"), [("so101", "so101_follower"), ("koch", "koch_follower")])
def test_the_simulated_follower_has_the_stiffness_the_check_assumes(arm: str, robot: str) -> None:
    kp, limited, _ = _loop(robot)
    sim = TELEOP_ARMS[arm]
    assert sim.kp_nm_rad == pytest.approx(tuple(kp[j] for j in sim.joints), rel=1e-12)
    assert sim.goal_limited == any(limited.values())
