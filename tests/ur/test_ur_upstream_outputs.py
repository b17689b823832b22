"""``--rpy upstream`` against numbers produced by UR's own C++ ``ur_calibration``, pinned as data.

The numbers below were produced outside this repository: ``ur_calibration/src/calibration.cpp`` of
UniversalRobots/Universal_Robots_ROS2_Driver (commit baf73e65, the ``atan2 − π`` version) built with g++ 12.2.0,
Eigen 3.4.0 and yaml-cpp 0.7.0 (rclcpp logging stubbed). For each of the three delta sets of upstream's
``test/calibration_test.cpp`` the driver built ``robot = base model + deltas`` (α = ±1.570796327), ran
``correctChain()`` and ``toYaml()``, set ``hash`` as ``CalibrationConsumer`` does, and printed every value with 17
significant digits. The only difference in the written YAML is that upstream writes the shoulder roll as ``-0``
and robocal writes ``0.0`` (on purpose).

Measured difference against robocal: 0 for all 108 values and the three hashes (bit-identical, same Euler
branch). The tolerance allows a couple of ulps so that another libm cannot fail the test; a change in the
order of operations or in an Euler-angle branch is far above it.
"""

from __future__ import annotations

import math
import re
from pathlib import Path

import numpy as np
import pytest

from robocal.cli.main import main
from robocal.core.dh import fk_dh
from robocal.core.se3 import rotation_angle_between
from robocal.core.ur import LINK_NAMES, UrKinematics, correct_kinematics, fk_origins
from robocal.formats.ur_kinematics import read_kinematics

from .conftest import calibrated_dh

TOL = 1e-15
"""Largest allowed |robocal − upstream| per value (measured: 0)."""

# (x, y, z, roll, pitch, yaw) per link, as ur_calibration's toYaml() writes them (roll, pitch, yaw are Eigen's
# eulerAngles(0, 1, 2), not URDF rpy).
UPSTREAM: dict[int, dict[str, tuple[float, float, float, float, float, float]]] = {
    1: {
        "shoulder": (0.0, 0.0, 0.12795609212979853, -0.0, 0.0, -7.2900700708247458e-05),
        "upper_arm": (4.6311376834935676e-05, 0.0, 0.0, 1.5710083148638694, 0.0, -2.2434108118307702e-05),
        "forearm": (
            -0.6122153631373195,
            0.0,
            0.0,
            3.1343383537539844,
            3.1414684740475196,
            -3.1415039327216476,
        ),
        "wrist_1": (
            -0.57115943082793208,
            0.0022026663436361315,
            0.16359445247178911,
            3.1281292798514859,
            3.1408612138948739,
            -3.1415846709038369,
        ),
        "wrist_2": (
            9.9185938706792656e-05,
            -0.11568415966109608,
            -0.0001561253807082875,
            1.572145909022733,
            0.0,
            1.4889842570257412e-07,
        ),
        "wrist_3": (
            4.2154627204531889e-06,
            0.092218998867213631,
            -0.00011648523331322634,
            1.5695331904261132,
            3.1415926535897931,
            -3.1415771385949962,
        ),
    },
    2: {
        "shoulder": (0.0, 0.0, 0.18055510502488192, -0.0, 0.0, 1.5961352531693174e-07),
        "upper_arm": (0.00010865106862793039, 0.0, 0.0, 1.5703515450471581, 0.0, -3.0149853382788194e-06),
        "forearm": (
            -0.61241972722243587,
            0.0,
            0.0,
            3.1406184807441364,
            3.1403206960406118,
            3.1415879492305567,
        ),
        "wrist_1": (
            -0.57126192649091689,
            -0.0010980373099151741,
            0.17419956776944939,
            0.0063032462245922911,
            -0.00044844113136731362,
            6.0399191132809665e-06,
        ),
        "wrist_2": (
            2.630761491656844e-05,
            -0.11980501351603139,
            0.00019774461638660047,
            1.5691457745265918,
            0.0,
            -1.642589765260549e-06,
        ),
        "wrist_3": (
            3.9663863250001272e-06,
            0.11567925223940098,
            8.8342215794385225e-05,
            1.5715600091053381,
            3.1415926535897931,
            -3.1415925618611831,
        ),
    },
    3: {
        "shoulder": (0.0, 0.0, 0.18053981171425867, -0.0, 0.0, -2.414780689435903e-07),
        "upper_arm": (2.1223486557120589e-05, 0.0, 0.0, 1.5701460804424159, 0.0, 1.8911545096818167e-06),
        "forearm": (
            -0.61254077444927835,
            0.0,
            0.0,
            3.141548687014847,
            3.1401991803606228,
            3.1415877613168126,
        ),
        "wrist_1": (
            -0.57135416827041818,
            -0.0012065472712251624,
            0.1745080134426083,
            0.0069138833359296522,
            -0.00058024688848003832,
            5.7687545358446516e-06,
        ),
        "wrist_2": (
            -4.6140902372093391e-05,
            -0.11981130168675538,
            9.7243828872839387e-05,
            1.5699846854376098,
            0.0,
            -1.0126035587115778e-07,
        ),
        "wrist_3": (
            -6.3928005347180152e-05,
            0.11567090748208292,
            4.7554660802913675e-05,
            1.5712074470943638,
            3.1415926535897931,
            -3.1415926143911723,
        ),
    },
}

UPSTREAM_HASH = {
    1: "calib_2432417391825271439",
    2: "calib_12699676364380556618",
    3: "calib_8779175261365510310",
}

# Upstream's YAML read as URDF rpy (R = Rz·Ry·Rx) vs the DH FK, max over 1000 q in [-2π, 2π] (seed 7):
# position m, rotation rad. Measured 4.318e-5 / 6.185e-5, 6.702e-6 / 7.327e-6, 3.279e-6 / 2.960e-6.
UPSTREAM_URDF_ERROR = {1: (4.318e-5, 6.185e-5), 2: (6.702e-6, 7.327e-6), 3: (3.279e-6, 2.960e-6)}

SETS = pytest.mark.parametrize("set_id", [1, 2, 3], ids=["set1", "set2", "set3"])


def _max_diff(kin: UrKinematics, set_id: int) -> float:
    assert [lk.name for lk in kin.links] == list(LINK_NAMES)
    worst = 0.0
    for lk in kin.links:
        got = (*lk.xyz_m, *lk.rpy_rad)
        for g, u in zip(got, UPSTREAM[set_id][lk.name], strict=True):
            worst = max(worst, abs(g - u))
    return worst


@SETS
def test_core_upstream_mode_equals_compiled_ur_calibration(set_id: int) -> None:
    kin = correct_kinematics(calibrated_dh(set_id), "upstream")
    assert kin.hash == UPSTREAM_HASH[set_id]
    assert kin.rpy_convention == "upstream"
    assert _max_diff(kin, set_id) <= TOL


@SETS
def test_cli_correct_rpy_upstream_file_equals_compiled_ur_calibration(
    tmp_path: Path, set_id: int, capsys: pytest.CaptureFixture[str]
) -> None:
    dh = calibrated_dh(set_id)
    dh_file = tmp_path / "dh.yaml"
    dh_file.write_text(
        "".join(
            f"{key}: [{', '.join(repr(float(v)) for v in vals)}]\n"
            for key, vals in (
                ("dh_theta", dh.theta_rad),
                ("dh_a", dh.a_m),
                ("dh_d", dh.d_m),
                ("dh_alpha", dh.alpha_rad),
            )
        )
    )
    out = tmp_path / "cal.yaml"
    assert main(["ur", "correct", "--dh", str(dh_file), "--out", str(out), "--rpy", "upstream"]) == 0
    capsys.readouterr()
    kin = read_kinematics(out)  # through the written text (shortest round-trip floats)
    assert kin.hash == UPSTREAM_HASH[set_id]
    assert _max_diff(kin, set_id) <= TOL
    assert re.search(r": -0(\.0)?$", out.read_text(), re.MULTILINE) is None  # upstream's "-0" → 0.0


@SETS
def test_upstream_yaml_as_urdf_rpy_is_off_by_reference_magnitudes(set_id: int) -> None:
    # The pinned upstream numbers themselves (not robocal's output) through URDF semantics.
    xyz = np.array([UPSTREAM[set_id][name][:3] for name in LINK_NAMES])
    rpy = np.array([UPSTREAM[set_id][name][3:] for name in LINK_NAMES])
    q = np.random.default_rng(7).uniform(-2 * math.pi, 2 * math.pi, (1000, 6))
    T_up = fk_origins(xyz, rpy, q)
    T_dh = fk_dh(calibrated_dh(set_id), q)
    pos = float(np.max(np.linalg.norm(T_up[:, :3, 3] - T_dh[:, :3, 3], axis=1)))
    rot = float(np.max(rotation_angle_between(T_up[:, :3, :3], T_dh[:, :3, :3])))
    exp_pos, exp_rot = UPSTREAM_URDF_ERROR[set_id]
    assert pos == pytest.approx(exp_pos, rel=0.01)
    assert rot == pytest.approx(exp_rot, rel=0.01)
    # robocal's default (URDF-convention angles, same translations) removes that error
    ok = correct_kinematics(calibrated_dh(set_id), "urdf")
    np.testing.assert_allclose(ok.xyz_array(), xyz, rtol=0, atol=TOL)
    T_ok = fk_origins(ok.xyz_array(), ok.rpy_array(), q)
    assert np.max(np.linalg.norm(T_ok[:, :3, 3] - T_dh[:, :3, 3], axis=1)) <= 1e-12
    assert np.max(rotation_angle_between(T_ok[:, :3, :3], T_dh[:, :3, :3])) <= 1e-12
