"""LeRobot arms as robot profiles (schema version 2, ``lerobot`` section): the facts, the parser, the users."""

from __future__ import annotations

from pathlib import Path

import pytest

from robocal.core.lerobot import LeRobotMotor, RobotSpec
from robocal.dataset.lerobot import motor_family_for_robot, preset_modes
from robocal.errors import FileFormatError, UsageError
from robocal.formats.profiles import builtin_lerobot_profiles, load_profile, parse_profile, profile_for_joints
from robocal.workflows.lerobot import robot_names, robot_spec

ARM = ("shoulder_pan", "shoulder_lift", "elbow_flex", "wrist_flex", "wrist_roll", "gripper")
SO_MODES = ("degrees",) * 5 + ("range_0_100",)
KOCH_MODES = ("range_m100_100",) * 5 + ("range_0_100",)


def _motors(
    models: tuple[str, ...],
    modes: tuple[str, ...],
    legacy: tuple[str, ...],
    *,
    gains: dict[str, tuple[int, int, int]] | None = None,
    run_modes: dict[str, int] | None = None,
) -> tuple[LeRobotMotor, ...]:
    return tuple(
        LeRobotMotor(n, i, mo, md, lg, (run_modes or {}).get(n), (gains or {}).get(n))
        for i, (n, mo, md, lg) in enumerate(zip(ARM, models, modes, legacy, strict=True), 1)
    )


# LeRobot 0.6.1: so_follower.py / so_leader.py (registered as so100_* and so101_*), koch_follower.py,
# koch_leader.py (Motor(id, model, norm_mode) per motor; calibrate() writes Operating_Mode, forces the
# full-turn motors to 0..4095 and sets the Koch leader's elbow_flex Drive_Mode to 1); legacy calib_mode of
# the 2024 scheme: Feetech gripper LINEAR, everything else DEGREE. configure(): the SO followers' P/I/D 16/0/32
# on every motor; the Koch follower's elbow_flex Position P/I/D 1500/0/600; both Koch arms run the gripper in
# current-based position (5), the other motors in extended position (4).
SO_LEGACY = ("DEGREE",) * 5 + ("LINEAR",)
EXPECTED = {
    f"{gen}_{role}": RobotSpec(
        f"{gen}_{role}",
        f"so_{role}",
        f"{gen}_{role}",
        "robots" if role == "follower" else "teleoperators",
        "feetech",
        _motors(
            ("sts3215",) * 6,
            SO_MODES,
            SO_LEGACY,
            gains=dict.fromkeys(ARM, (16, 0, 32)) if role == "follower" else None,
        ),
        ("wrist_roll",),
        0,
    )
    for gen in ("so100", "so101")
    for role in ("follower", "leader")
}
EXPECTED["koch_follower"] = RobotSpec(
    "koch_follower",
    "koch_follower",
    "koch_follower",
    "robots",
    "dynamixel",
    _motors(
        ("xl430-w250",) * 2 + ("xl330-m288",) * 4,
        KOCH_MODES,
        ("DEGREE",) * 6,
        gains={"elbow_flex": (1500, 0, 600)},
        run_modes={"gripper": 5},
    ),
    ("shoulder_pan", "wrist_roll"),
    4,
)
EXPECTED["koch_leader"] = RobotSpec(
    "koch_leader",
    "koch_leader",
    "koch_leader",
    "teleoperators",
    "dynamixel",
    _motors(("xl330-m077",) * 6, KOCH_MODES, ("DEGREE",) * 6, run_modes={"gripper": 5}),
    ("shoulder_pan", "wrist_roll"),
    4,
    ("elbow_flex",),
)


@pytest.mark.parametrize("name", sorted(EXPECTED))
def test_profiles_hold_lerobots_presets(name: str) -> None:
    assert robot_spec(name) == EXPECTED[name]
    profile = load_profile(name)
    assert profile.version == 2 and profile.lerobot is not None
    assert profile.joint_names == ARM


def test_the_lerobot_arms_are_exactly_the_six_profiles() -> None:
    assert robot_names() == tuple(sorted(EXPECTED))
    assert tuple(p.name for p in builtin_lerobot_profiles()) == robot_names()


def test_lerobot_arms_are_not_guessed_from_joint_names() -> None:
    # six profiles share these motor names: recognition stays with the robots whose joints are unique
    assert profile_for_joints(ARM) is None


def _doc(version: int = 2, **lerobot: object) -> dict[str, object]:
    section: dict[str, object] = {
        "device_name": "my_arm",
        "old_device_name": "my_arm",
        "kind": "robots",
        "vendor": "feetech",
        "operating_mode": 0,
    }
    section.update(lerobot)
    return {
        "format": "robocal-robot-profile",
        "version": version,
        "name": "my_arm",
        "lerobot": section,
        "joints": [
            {"name": "a", "id": 1, "model": "sts3215", "norm_mode": "degrees"},
            {
                "name": "gripper",
                "id": 2,
                "model": "sts3215",
                "norm_mode": "range_0_100",
                "legacy_mode": "LINEAR",
            },
        ],
    }


def test_a_profile_of_your_own_arm(tmp_path: Path) -> None:
    profile = parse_profile(_doc(full_turn=["a"]), "mine.yaml")
    spec = RobotSpec.from_profile(profile)
    assert spec.motors == (
        LeRobotMotor("a", 1, "sts3215", "degrees", "DEGREE"),
        LeRobotMotor("gripper", 2, "sts3215", "range_0_100", "LINEAR"),
    )
    assert spec.full_turn == ("a",) and spec.inverted == () and spec.kind == "robots"
    path = tmp_path / "mine.yaml"
    path.write_text(
        "format: robocal-robot-profile\nversion: 2\nname: mine\n"
        "lerobot: {device_name: so_follower, old_device_name: mine, kind: robots, vendor: feetech, "
        "operating_mode: 0}\n"
        "joints:\n  - {name: a, id: 3, model: sts3215, norm_mode: range_m100_100}\n"
    )
    assert robot_spec(str(path)).motors == (LeRobotMotor("a", 3, "sts3215", "range_m100_100"),)


@pytest.mark.parametrize(
    ("doc", "message"),
    [
        (_doc(version=1), r"unknown key lerobot"),
        (_doc(kind="robot"), r"lerobot: kind 'robot'; expected one of robots, teleoperators"),
        (_doc(vendor="robstride"), r"vendor 'robstride'; expected one of feetech, dynamixel"),
        (_doc(inverted=["elbow"]), r"inverted names no joint of the profile: elbow"),
        (_doc(colour="red"), r"lerobot: unknown key colour"),
        (_doc(operating_mode=None), r"lerobot: missing key operating_mode"),
        (_doc(version=3), r"version 3 is not supported \(expected 1 or 2\)"),
    ],
)
def test_a_bad_lerobot_section_is_named(doc: dict[str, object], message: str) -> None:
    with pytest.raises(FileFormatError, match=message):
        parse_profile(doc, "mine.yaml")


def test_a_lerobot_joint_needs_id_model_and_norm_mode() -> None:
    doc = _doc()
    doc["joints"] = [{"name": "a", "id": 1, "norm_mode": "degrees"}]
    with pytest.raises(FileFormatError, match=r"joint 'a': a LeRobot arm needs model"):
        parse_profile(doc, "mine.yaml")
    doc["joints"] = [{"name": "a", "id": 1, "model": "x", "norm_mode": "DEGREES"}]
    with pytest.raises(
        FileFormatError, match=r"joint 'a': norm_mode 'DEGREES'; expected one of range_m100_100"
    ):
        parse_profile(doc, "mine.yaml")


def test_version_1_joints_refuse_the_lerobot_keys() -> None:
    doc = {
        "format": "robocal-robot-profile",
        "version": 1,
        "name": "x",
        "joints": [{"name": "a", "norm_mode": "degrees"}],
    }
    with pytest.raises(FileFormatError, match=r"joint 'a': unknown key norm_mode"):
        parse_profile(doc, "old.yaml")


def test_a_profile_without_lerobot_section_is_not_an_arm() -> None:
    with pytest.raises(UsageError, match=r"robot profile bhl_biped is not a LeRobot arm"):
        robot_spec_of_profile("bhl_biped")
    with pytest.raises(
        UsageError, match=r"unknown robot 'bhl_biped'; valid: koch_follower, koch_leader, so100"
    ):
        robot_spec("bhl_biped")


def robot_spec_of_profile(name: str) -> RobotSpec:
    return RobotSpec.from_profile(load_profile(name))


@pytest.mark.parametrize(
    ("robot", "family", "arm_mode"),
    [
        ("so100_follower", "feetech", "degrees"),
        ("so100", "feetech", "degrees"),
        ("so101_leader", "feetech", "degrees"),
        ("lekiwi", "feetech", "degrees"),
        ("koch_follower", "dynamixel", "range_m100_100"),
        ("koch_leader", "dynamixel", "range_m100_100"),
        ("koch_bimanual", "dynamixel", "range_m100_100"),
    ],
)
def test_dataset_presets_come_from_the_profiles(robot: str, family: str, arm_mode: str) -> None:
    assert motor_family_for_robot(robot) == family
    assert preset_modes(robot, ["elbow_flex", "gripper"]) == {
        "elbow_flex": arm_mode,
        "gripper": "range_0_100",
    }


def test_dataset_unknown_robot_type_lists_the_profiles_prefixes() -> None:
    with pytest.raises(UsageError, match=r"unknown robot type; known: so\*, koch\*, lekiwi\*"):
        motor_family_for_robot("aloha")


def _with_joint_keys(**keys: object) -> dict[str, object]:
    doc = _doc()
    joints = doc["joints"]
    assert isinstance(joints, list)
    joints[0] = {**joints[0], **keys}
    return doc


def test_a_motors_run_mode_and_gains() -> None:
    spec = RobotSpec.from_profile(parse_profile(_with_joint_keys(position_gains=[16, 0, 32], operating_mode=3), "m"))
    a, gripper = spec.motors
    assert (a.position_gains, a.operating_mode, spec.run_mode(a)) == ((16, 0, 32), 3, 3)
    assert (gripper.position_gains, gripper.operating_mode, spec.run_mode(gripper)) == (None, None, 0)


@pytest.mark.parametrize(
    ("keys", "message"),
    [
        ({"position_gains": [16, 0]}, r"joint 'a': position_gains \[16, 0\]; expected \[P, I, D\]"),
        ({"position_gains": "16"}, r"joint 'a': position_gains '16'; expected \[P, I, D\]"),
        ({"position_gains": [16, -1, 32]}, r"joint 'a': position_gains -1 is out of range; expected 0\.\.65535"),
        ({"position_gains": [16, 0, 1.5]}, r"joint 'a': position_gains 1\.5 is not an integer"),
        ({"operating_mode": 70000}, r"joint 'a': operating_mode 70000 is out of range"),
        ({"operating_mode": True}, r"joint 'a': operating_mode is True; expected an integer"),
    ],
)
def test_bad_gains_or_mode_are_named(keys: dict[str, object], message: str) -> None:
    with pytest.raises(FileFormatError, match=message):
        parse_profile(_with_joint_keys(**keys), "mine.yaml")


def test_a_version_1_profile_with_gains_is_refused() -> None:
    doc = _with_joint_keys(position_gains=[16, 0, 32])
    del doc["lerobot"]
    doc["version"] = 1
    with pytest.raises(FileFormatError, match=r"joint 'a'.*position_gains"):
        parse_profile(doc, "mine.yaml")
