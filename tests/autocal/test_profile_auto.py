"""The profiles' auto_calibration section: built-in values and every refusal."""

from __future__ import annotations

import copy
import math
from typing import Any

import pytest

from robocal.errors import FileFormatError
from robocal.formats.profiles import load_profile, parse_profile

BASE: dict[str, Any] = {
    "format": "robocal-robot-profile",
    "version": 2,
    "name": "t",
    "joints": [
        {"name": "a", "model": "rs-02"},
        {"name": "b", "model": "sts3215"},
    ],
    "auto_calibration": {
        "joints": [
            {"name": "a", "stops": "both"},
            {"name": "b", "stops": "upper", "upper_deg": 90, "rated_nm": 1.5, "pose": {"a": 10}},
        ]
    },
}


def doc(**changes: Any) -> dict[str, Any]:
    d = copy.deepcopy(BASE)
    for path, value in changes.items():
        node: Any = d
        keys = path.split("__")
        for k in keys[:-1]:
            node = node[int(k)] if k.isdigit() else node[k]
        last = keys[-1]
        if value is None:
            del node[int(last) if last.isdigit() else last]
        else:
            node[int(last) if last.isdigit() else last] = value
    return d


def test_defaults_and_model_rating() -> None:
    p = parse_profile(doc(), "t.yaml")
    assert p.auto is not None
    a, b = p.auto.joints
    assert a.rated_nm == 6.0  # RS02 rated torque
    assert a.torque_fraction == 0.25 and a.torque_cap_nm == pytest.approx(1.5)
    assert a.speed_deg_s == 10.0 and a.tolerance_deg == 15.0
    assert b.stops == "upper" and b.upper_deg == 90 and b.pose == (("a", 10.0),)
    assert b.expected_rad(-1.0, 1.0) == (-1.0, pytest.approx(math.pi / 2))


def test_builtin_lite_profile_has_14_joints() -> None:
    p = load_profile("bhl_arms")
    assert p.auto is not None
    assert len(p.auto.joints) == 14
    assert set(p.auto.joint_names) == set(p.joint_names)
    sp = p.auto.joint("left_shoulder_pitch")
    assert sp is not None and sp.torque_cap_nm == pytest.approx(0.3 * 6.0)
    assert p.auto.joint("left_wrist_roll").torque_cap_nm == pytest.approx(0.25 * 1.6)  # type: ignore[union-attr]


@pytest.mark.parametrize(
    ("changes", "message"),
    [
        ({"version": 1}, "needs version 2"),
        ({"version": 3}, "version 3 is not supported"),
        ({"auto_calibration__max_torque_fraction": 0.6}, "above the hard limit 0.5"),
        (
            {"auto_calibration__joints__0__torque_fraction": 0.4},
            "above the profile's max_torque_fraction 0.3",
        ),
        ({"auto_calibration__speed_deg_s": 45}, "speed_deg_s 45 is above the hard limit 30"),
        ({"auto_calibration__joints__0__speed_deg_s": -1}, "speed_deg_s must be a positive number"),
        ({"auto_calibration__joints__0__bogus": 1}, "unknown key bogus"),
        ({"auto_calibration__joints__0__name": "zz"}, "not a joint of the profile"),
        ({"auto_calibration__joints__1__upper_deg": None}, "needs upper_deg"),
        ({"joints__1__model": "mystery"}, "motor model 'mystery' has no known rating"),
        ({"auto_calibration__joints__1__rated_nm": 2.0}, "rated_nm 2 N·m is above the STS3215's rated torque 1.91"),
        ({"auto_calibration__joints__0__rated_nm": 1e9}, "rated_nm 1e[+]09 N·m is above the RS02's rated torque 6"),
        ({"auto_calibration__joints__0__rated_nm": -1}, "rated_nm must be a positive number"),
        ({"auto_calibration__joints__1__motor": "rs-05"}, "motor 'rs-05' answers as 'rs-05' on the bus"),
        ({"auto_calibration__joints__1__motor": "sts9999"}, "motor 'sts9999' is not a motor model robocal knows"),
        ({"auto_calibration__joints__0__pose": {"b": 1}}, "not calibrated before it"),
        ({"auto_calibration__joints__0__stops": "middle"}, "stops 'middle'"),
        (
            {"auto_calibration__joints__0__lower_deg": 5, "auto_calibration__joints__0__upper_deg": 5},
            "must be below",
        ),
        ({"auto_calibration__second_touch": "yes"}, "second_touch"),
        ({"auto_calibration__joints": []}, "non-empty list"),
        ({"auto_calibration__joints__0__rated_nm": math.nan}, "rated_nm"),
        ({"auto_calibration__joints__1__stops": "none"}, "takes no pose"),
        (
            {"auto_calibration__joints__0__stops": "none", "auto_calibration__joints__1__pose": None},
            "needs a reason",
        ),
        (
            {
                "auto_calibration__joints__0__stops": "none",
                "auto_calibration__joints__0__reason": "full turn",
            },
            "pose names 'a', which is not searched",
        ),
        ({"auto_calibration__joints__0__reason": "why"}, "reason is for joints that are not searched"),
        ({"auto_calibration__joints__1__reason": 5}, "reason must be text"),
    ],
)
def test_refused(changes: dict[str, Any], message: str) -> None:
    with pytest.raises(FileFormatError, match=message) as info:
        parse_profile(doc(**changes), "t.yaml")
    assert "profile t.yaml" in str(info.value)


def test_duplicate_joint_refused() -> None:
    d = doc()
    d["auto_calibration"]["joints"].append({"name": "a"})
    with pytest.raises(FileFormatError, match="'a': appears twice"):
        parse_profile(d, "t.yaml")


def test_lerobot_followers_have_auto_sections() -> None:
    so = load_profile("so101_follower").auto
    assert so is not None
    assert so.joint_names == (
        "shoulder_lift",
        "elbow_flex",
        "wrist_flex",
        "wrist_roll",
        "gripper",
        "shoulder_pan",
    )
    assert so.joint("shoulder_lift").torque_cap_nm == pytest.approx(0.45 * 1.91)  # type: ignore[union-attr]
    assert so.joint("wrist_flex").pose == (("shoulder_lift", 0.0), ("elbow_flex", 0.0))  # type: ignore[union-attr]
    koch = load_profile("koch_follower").auto
    assert koch is not None
    # LeRobot's full-turn motors have no hard stop: listed with stops: none, never searched
    assert [j.name for j in koch.joints if not j.searched] == ["shoulder_pan", "wrist_roll"]
    assert koch.joint("wrist_roll").stops == "none"  # type: ignore[union-attr]
    assert koch.joint("elbow_flex").torque_cap_nm == pytest.approx(0.13)  # type: ignore[union-attr]


def test_joint_without_stops_is_not_searched() -> None:
    d = doc()
    d["auto_calibration"]["joints"].append({"name": "c", "stops": "none", "reason": "  full-turn motor  "})
    d["joints"].append({"name": "c", "model": "xl330-m288"})
    p = parse_profile(d, "t.yaml")
    assert p.auto is not None
    c = p.auto.joint("c")
    assert c is not None and c.stops == "none" and not c.searched and c.reason == "full-turn motor"
    assert c.torque_cap_nm == 0.0
    assert [j.name for j in p.auto.searched_joints] == ["a", "b"]
    # a none joint takes no torque or speed of its own
    d["auto_calibration"]["joints"][2]["torque_fraction"] = 0.2
    with pytest.raises(
        FileFormatError, match=r"'c': a joint that is not searched .* takes no torque_fraction"
    ):
        parse_profile(d, "t.yaml")
    # at least one joint must move
    only = doc()
    only["auto_calibration"]["joints"] = [{"name": "a", "stops": "none", "reason": "x"}]
    with pytest.raises(FileFormatError, match="every joint has stops: none"):
        parse_profile(only, "t.yaml")
