from __future__ import annotations

from pathlib import Path

import pytest
from lite_testutil import (
    BIMANUAL_URDF,
    BIPED_URDF,
    FULL_URDF,
    UPSTREAM_DIRS,
    UPSTREAM_IDEAL_DEG,
    UPSTREAM_IDS,
    UPSTREAM_ORDER,
    UPSTREAM_SIDE,
    URDF_ORDER,
)

from robocal.backends.sim.lite import LITE_JOINTS
from robocal.cli.main import main
from robocal.errors import FileFormatError, JointMismatchError, UsageError
from robocal.formats.profiles import (
    builtin_profile_names,
    load_profile,
    recognise_profile,
    resolve_profile,
)
from robocal.formats.urdf import read_urdf


def test_bhl_biped_profile_holds_the_upstream_facts() -> None:
    p = load_profile("bhl_biped")
    assert p.upstream_names == tuple(UPSTREAM_ORDER)
    assert p.joint_names == tuple(URDF_ORDER)
    assert [j.motor_id for j in p.joints] == UPSTREAM_IDS
    assert [j.direction for j in p.joints] == UPSTREAM_DIRS
    assert [j.bus for j in p.joints] == ["can0"] * 6 + ["can1"] * 6
    assert [{"min": "lower", "max": "upper"}[s] for s in UPSTREAM_SIDE] == [j.stop for j in p.joints]
    assert [j.stop_deg for j in p.joints] == UPSTREAM_IDEAL_DEG
    assert p.method == "one-sided" and p.file_format == "berkeley-offsets" and not p.position_wraps


def test_bhl_arms_profile_is_the_seed_bimanual_table() -> None:
    p = load_profile("bhl_arms")
    assert p.joint_names == tuple(j.name for j in LITE_JOINTS)
    assert [(j.motor_id, j.direction, j.bus, j.model) for j in p.joints] == [
        (j.can_id, j.direction, j.bus, j.model) for j in LITE_JOINTS
    ]
    assert p.method == "two-sided" and p.file_format == "lite-yaml"


def test_profile_stop_angles_are_the_official_urdf_limits() -> None:
    """The stop each joint is pushed into is the URDF limit on that side (to the URDF's 6 digits)."""
    urdf = read_urdf(BIPED_URDF)
    for j in load_profile("bhl_biped").joints:
        lo, up = urdf.limits(j.name)
        assert j.stop_rad == pytest.approx(lo if j.stop == "lower" else up, abs=1e-6)


@pytest.mark.parametrize(
    ("urdf", "name"), [(BIPED_URDF, "bhl_biped"), (FULL_URDF, "bhl_biped"), (BIMANUAL_URDF, "bhl_arms")]
)
def test_profile_recognised_from_urdf_joint_names(urdf: Path, name: str) -> None:
    profile = recognise_profile(read_urdf(urdf))
    assert profile is not None and profile.name == name


def test_unknown_urdf_has_no_profile(tmp_path: Path) -> None:
    p = tmp_path / "r.urdf"
    p.write_text(BIPED_URDF.read_text().replace("leg_left_knee_pitch_joint", "knee"))
    assert recognise_profile(read_urdf(p)) is None


def test_robot_names_a_builtin_or_a_file(tmp_path: Path) -> None:
    koch = ("koch_follower", "koch_leader")
    openarm = tuple(f"openarm_{r}_{s}" for r in ("follower", "leader") for s in ("left", "right"))
    so = tuple(f"{a}_{r}" for a in ("so100", "so101") for r in ("follower", "leader"))
    assert builtin_profile_names() == ("bhl_arms", "bhl_biped", *koch, *openarm, *so)
    with pytest.raises(UsageError, match=r"--robot 'nao': not a built-in robot \(bhl_arms, bhl_biped, koch_"):
        load_profile("nao")
    with pytest.raises(
        JointMismatchError, match=r"--robot bhl_arms: URDF .* has no joint left_shoulder_pitch"
    ):
        resolve_profile("bhl_arms", read_urdf(BIPED_URDF))


def _write_profile(tmp_path: Path, joints: str, extra: str = "") -> Path:
    p = tmp_path / "mine.yaml"
    p.write_text("format: robocal-robot-profile\nversion: 1\nname: mine\n" + extra + "joints:\n" + joints)
    return p


@pytest.mark.parametrize(
    ("joints", "extra", "message"),
    [
        ("  - {name: a, direction: 2}\n", "", "joint 'a': direction 2 is invalid"),
        ("  - {name: a, stop: lower}\n", "", "joint 'a': stop and stop_deg go together"),
        ("  - {name: a, stop: side, stop_deg: 1}\n", "", "joint 'a': stop 'side'; expected lower or upper"),
        ("  - {name: a, colour: red}\n", "", "joint 'a': unknown key colour"),
        ("  - {name: a, id: 1}\n  - {name: b, id: 1}\n", "", "joints 'a' and 'b' share id 1"),
        ("  - {name: a}\n  - {name: a}\n", "", "name 'a' appears twice"),
        (
            "  - {name: a}\n",
            "calibration: {method: one-sided}\n",
            "needs stop and stop_deg for every joint; missing for a",
        ),
        (
            "  - {name: a, stop: lower, stop_deg: .nan}\n",
            "",
            "joint .a.: stop_deg is nan; expected a finite number",
        ),
        ("  []\n", "", "joints must be a non-empty list"),
    ],
)
def test_malformed_profile_names_the_problem(tmp_path: Path, joints: str, extra: str, message: str) -> None:
    with pytest.raises(FileFormatError, match=message):
        load_profile(_write_profile(tmp_path, joints, extra))


def test_own_profile_file_with_robot_flag(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """A user's profile (other directions) is used by --robot PATH and disagreements are named."""
    rows = "".join(
        f"  - {{name: {n}, direction: {-d if i == 0 else d}, id: {mid}}}\n"
        for i, (n, d, mid) in enumerate(zip(URDF_ORDER, UPSTREAM_DIRS, UPSTREAM_IDS, strict=True))
    )
    mine = _write_profile(tmp_path, rows)
    lite = tmp_path / "c.yaml"
    assert main(["convert", str(BIPED_URDF.parent / "calibration.yaml"), str(lite), "--to", "lite-yaml",
                 "--urdf", str(BIPED_URDF)]) == 0  # fmt: skip
    capsys.readouterr()
    rc = main(["check", "--calibration", str(lite), "--urdf", str(BIPED_URDF), "--robot", str(mine)])
    out = capsys.readouterr()
    assert rc == 1
    assert "robot profile: mine (--robot)" in out.out
    assert "leg_left_hip_roll_joint: direction -1 in the file disagrees with +1 in profile mine" in out.err


def test_joint_direction_and_id_precedence_is_urdf_then_file_then_profile() -> None:
    from robocal.formats.profiles import joint_direction, joint_motor_id
    from robocal.formats.urdf import parse_urdf

    hip, yaw = "leg_left_hip_roll_joint", "leg_left_hip_yaw_joint"  # profile: direction -1 / +1, ids 1 / 3
    urdf = parse_urdf(
        '<robot name="r"><link name="a"/><link name="b"/><link name="c"/>'
        f'<joint name="{hip}" type="revolute"><parent link="a"/><child link="b"/><axis xyz="1 0 0"/>'
        '<limit lower="-1" upper="1" effort="1" velocity="1"/></joint>'
        f'<joint name="{yaw}" type="revolute"><parent link="b"/><child link="c"/><axis xyz="0 0 1"/>'
        '<limit lower="-1" upper="1" effort="1" velocity="1"/></joint>'
        '<ros2_control name="s" type="system">'
        f'<joint name="{hip}"><param name="direction">1</param><param name="can_id">21</param></joint>'
        f'<joint name="{yaw}"/></ros2_control></robot>'
    )
    biped = load_profile("bhl_biped")
    assert joint_direction(hip, urdf, biped, {hip: -1}) == 1  # the URDF's param first
    assert joint_direction(yaw, urdf, biped, {yaw: -1}) == -1  # then the file's
    assert joint_direction(yaw, urdf, biped) == 1  # then the profile's
    assert joint_direction(yaw, None, None) is None
    assert (joint_motor_id(hip, urdf, biped), joint_motor_id(yaw, urdf, biped)) == (21, 3)
    assert joint_motor_id(yaw, urdf, None) is None
