"""The shipped OpenArm v10 profiles and URDFs: the facts of openarm_description / LeRobot / openarm_can, pinned."""

from __future__ import annotations

import math
from importlib import resources

import pytest

from robocal.backends.damiao.openarm import openarm_joints
from robocal.backends.damiao.openarm_urdf import openarm_urdf_joint, openarm_urdf_text
from robocal.core.motor_models import find_motor_model
from robocal.errors import FileFormatError, UsageError
from robocal.formats.profiles import load_profile, parse_profile, resolve_profile
from robocal.formats.urdf import read_urdf

PROFILES = ["openarm_follower_right", "openarm_follower_left", "openarm_leader_right", "openarm_leader_left"]
# design stop angles, joint frame, degrees (openarm_description v10 joint_limits.yaml + side transforms;
# the gripper from openarm_can's zero-position script, v1 -60..0)
STOPS_RIGHT = {
    "joint1": (-80, 200), "joint2": (-10, 190), "joint3": (-90, 90), "joint4": (0, 140),
    "joint5": (-90, 90), "joint6": (-45, 45), "joint7": (-90, 90), "gripper_motor": (-60, 0),
}
STOPS_LEFT = {**STOPS_RIGHT, "joint1": (-200, 80), "joint2": (-190, 10)}
MODELS = ["dm8009", "dm8009", "dm4340", "dm4340", "dm4310", "dm4310", "dm4310", "dm4310"]
LEROBOT = ["joint_1", "joint_2", "joint_3", "joint_4", "joint_5", "joint_6", "joint_7", "gripper"]


def test_damiao_ratings_are_the_openarm_datasheet_numbers() -> None:
    for name, rated, peak in (("DM4310", 3.0, 7.0), ("DM4340", 9.0, 27.0), ("DM8009", 20.0, 40.0)):
        m = find_motor_model(name.lower())
        assert m is not None and (m.family, m.rated_nm, m.stall_nm, m.ceiling_nm) == ("damiao", rated, peak, rated / 2)
        assert "motor.mdx" in m.source and f"rated {rated:g} / peak {peak:g}" in m.source
    assert find_motor_model("dm-4340") is find_motor_model("DM4340")


@pytest.mark.parametrize("name", PROFILES)
def test_profile_ids_models_order_and_directions(name: str) -> None:
    p = load_profile(name)
    side = "right" if name.endswith("right") else "left"
    assert p.actuator == "damiao" and p.position_wraps is True and p.method == "two-sided"
    assert [j.upstream_name for j in p.joints] == LEROBOT
    assert [j.name for j in p.joints] == [openarm_urdf_joint(side, n) for n in LEROBOT]  # type: ignore[arg-type]
    assert [(j.motor_id, j.reply_id) for j in p.joints] == [(n, 0x10 + n) for n in range(1, 9)]
    assert [j.model for j in p.joints] == MODELS
    assert {j.bus for j in p.joints} == {"can0" if side == "right" else "can1"}
    assert {j.direction for j in p.joints} == {1}


@pytest.mark.parametrize("name", PROFILES)
def test_auto_section_stops_caps_and_poses(name: str) -> None:
    p = load_profile(name)
    side = "right" if name.endswith("right") else "left"
    stops = STOPS_RIGHT if side == "right" else STOPS_LEFT
    auto = p.auto
    assert auto is not None and auto.max_torque_fraction == 0.5
    pre = f"openarm_{side}_"
    assert [j.name for j in auto.joints] == [pre + s for s in (
        "gripper_motor", "joint7", "joint6", "joint5", "joint4", "joint3", "joint2", "joint1")]
    for j in auto.joints:
        assert j.stops == "both"
        assert (j.lower_deg, j.upper_deg) == stops[j.name.removeprefix(pre)]
        model = find_motor_model(j.motor)
        assert model is not None and j.torque_cap_nm <= model.ceiling_nm + 1e-12
    caps = {j.name.removeprefix(pre): round(j.torque_cap_nm, 6) for j in auto.joints}
    assert caps == {"gripper_motor": 0.75, "joint7": 0.75, "joint6": 1.2, "joint5": 0.75, "joint4": 4.5,
                    "joint3": 2.25, "joint2": 10.0, "joint1": 10.0}
    j1 = auto.joint(pre + "joint1")
    assert j1 is not None and dict(j1.pose) == {pre + "joint2": 10 if side == "right" else -10, pre + "joint4": 45}
    assert auto.joint(pre + "joint4").park_deg == 10  # type: ignore[union-attr]  # never parked on its stop


@pytest.mark.parametrize("side", ["right", "left"])
def test_shipped_urdf_is_the_generator_and_the_simulated_arm(side: str) -> None:
    text = resources.files("robocal").joinpath("data", f"openarm_v10_{side}.urdf").read_text(encoding="utf-8")
    assert text == openarm_urdf_text(side)  # type: ignore[arg-type]
    urdf = read_urdf(str(resources.files("robocal").joinpath("data", f"openarm_v10_{side}.urdf")))
    truth = {openarm_urdf_joint(side, j.name): j for j in openarm_joints(side)}  # type: ignore[arg-type]
    assert list(urdf.joint_names) == list(truth)
    for name, j in truth.items():
        lo, hi = urdf.limits(name)
        assert lo == pytest.approx(j.stop_lower_rad, abs=5e-7) and hi == pytest.approx(j.stop_upper_rad, abs=5e-7)
    assert resolve_profile(f"openarm_follower_{side}", urdf).name == f"openarm_follower_{side}"  # type: ignore[union-attr]
    assert math.degrees(urdf.limits(f"openarm_{side}_joint1")[0]) == pytest.approx(-80 if side == "right" else -200,
                                                                                    abs=1e-4)


def test_openarm_urdf_is_recognised_follower_and_leader_having_the_same_joints() -> None:
    urdf = read_urdf(str(resources.files("robocal").joinpath("data", "openarm_v10_right.urdf")))
    assert resolve_profile(None, urdf).name == "openarm_follower_right"  # type: ignore[union-attr]
    assert load_profile("openarm_leader_right").joints == load_profile("openarm_follower_right").joints
    with pytest.raises(UsageError, match="no motor 'joint_9'"):
        openarm_urdf_joint("right", "joint_9")


def test_reply_id_is_a_version_2_key_and_an_id() -> None:
    doc = {"format": "robocal-robot-profile", "version": 2, "name": "t",
           "joints": [{"name": "a", "id": 1, "reply_id": 17}]}
    assert parse_profile(doc, "t.yaml").joints[0].reply_id == 17
    with pytest.raises(FileFormatError, match="reply_id"):
        parse_profile({**doc, "joints": [{"name": "a", "reply_id": -1}]}, "t.yaml")
    with pytest.raises(FileFormatError, match="reply_id"):
        parse_profile({**doc, "version": 1}, "t.yaml")
