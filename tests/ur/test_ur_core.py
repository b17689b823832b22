"""UR core: DH FK, the correction (upstream suite reproduced), the calib_ hash, rpy conventions."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from robocal.backends.ur_primary import encode_kinematics_info, parse_kinematics_info
from robocal.core.dh import DHParameters, fk_dh, fk_dh_loop
from robocal.core.se3 import (
    eigen_euler_xyz,
    matrix_from_rpy_urdf,
    rot_x,
    rot_y,
    rot_z,
    rotation_angle_between,
    rpy_urdf_from_matrix,
)
from robocal.core.ur import (
    UR_MODELS,
    correct_chain,
    correct_kinematics,
    default_kinematics,
    fk_origins,
    nominal_dh,
    six_transforms,
)
from robocal.core.urhash import calib_hash, cpp_ostream_format, hash_bytes_libstdcxx, kinematics_hash_string
from robocal.errors import (
    InvalidCalibrationError,
    ShapeMismatchError,
    UsageError,
)
from robocal.formats.ur_kinematics import kinematics_to_text

PI_2 = 1.570796327


def chain_fk(dh: DHParameters, q: np.ndarray) -> np.ndarray:
    """FK through the corrected six transforms: Π S_k · Rz(q_k)."""
    S = six_transforms(correct_chain(dh))
    T = np.broadcast_to(np.eye(4), (q.shape[0], 4, 4)).copy()
    for k in range(6):
        Rq = np.zeros((q.shape[0], 4, 4))
        Rq[:, :3, :3] = rot_z(q[:, k])
        Rq[:, 3, 3] = 1.0
        T = T @ S[k] @ Rq
    return T


# --- hash -------------------------------------------------------------------------------------------------

DEFAULT_HASHES = {
    "ur3": "calib_9122066269688285636",
    "ur5": "calib_209549117540498681",
    "ur10": "calib_17227329492635474227",
    "ur3e": "calib_16756443741236045476",
    "ur5e": "calib_12788084448423163542",
    "ur10e": "calib_5119701370761913513",
    "ur16e": "calib_1935737212149401527",
    "ur20": "calib_4890363623803256388",
    "ur30": "calib_12001109639981648826",
}


@pytest.mark.parametrize("model", sorted(DEFAULT_HASHES))
def test_default_kinematics_hash_matches_ur_description(model: str) -> None:
    dh = nominal_dh(model)
    assert calib_hash(dh.theta_rad, dh.d_m, dh.a_m, dh.alpha_rad) == DEFAULT_HASHES[model]
    assert default_kinematics(model).hash == DEFAULT_HASHES[model]


def test_hash_string_of_nominal_ur5e() -> None:
    dh = nominal_dh("ur5e")
    s = kinematics_hash_string(dh.theta_rad, dh.d_m, dh.a_m, dh.alpha_rad)
    assert s == "00.162501.570800-0.425000-0.3922000.133301.570800.09970-1.570800.099600"
    assert f"calib_{hash_bytes_libstdcxx(s.encode())}" == "calib_12788084448423163542"


def test_hash_of_test_sets(dh_sets: dict[int, DHParameters]) -> None:
    d1, d2 = dh_sets[1], dh_sets[2]
    assert calib_hash(d1.theta_rad, d1.d_m, d1.a_m, d1.alpha_rad) == "calib_2432417391825271439"
    assert calib_hash(d2.theta_rad, d2.d_m, d2.a_m, d2.alpha_rad) == "calib_12699676364380556618"


@pytest.mark.parametrize(
    ("value", "text"),
    [
        (0.0, "0"),
        (-0.0, "-0"),
        (0.1625, "0.1625"),
        (1.570796327, "1.5708"),
        (-0.3922, "-0.3922"),
        (1e-5, "1e-05"),
        (439.140974079901, "439.141"),
        (123456789.0, "1.23457e+08"),
        (math.inf, "inf"),
    ],
)
def test_cpp_ostream_format(value: float, text: str) -> None:
    assert cpp_ostream_format(value) == text


def test_hash_bytes_tail_lengths_differ() -> None:
    # every tail length 0..8 goes through a different code path; all distinct and stable
    hashes = {hash_bytes_libstdcxx(b"x" * n) for n in range(17)}
    assert len(hashes) == 17
    assert hash_bytes_libstdcxx(b"") == hash_bytes_libstdcxx(b"")


# --- DH forward kinematics ------------------------------------------------------------------------------------

URSIM_CASES = [
    (
        (
            -1.6007002035724084976209269370884,
            -1.7271001974688928726209269370884,
            -2.2029998938189905288709269370884,
            -0.80799991289247685699592693708837,
            1.59510004520416259765625,
            -0.03099996248354131012092693708837,
        ),
        (-0.179925914147547, -0.606869755162764, 0.230789102067257),
    ),
    (
        (
            1.32645022869110107421875,
            2.426007747650146484375,
            5.951572895050048828125,
            1.27409040927886962890625,
            -0.54105216661562138824592693708837,
            0.122173048555850982666015625,
        ),
        (
            0.39922988003280424074148413637886,
            0.59688365069340565405298093537567,
            -0.6677819040276375961440180617501,
        ),
    ),
]


@pytest.mark.parametrize(("q", "p"), URSIM_CASES)
def test_ursim_fk_positions_within_1e15(q: tuple[float, ...], p: tuple[float, ...]) -> None:
    T = fk_dh(nominal_dh("ur10"), np.array(q))
    assert np.max(np.abs(T[:3, 3] - np.array(p))) < 1e-15


def _ur10_ideal() -> DHParameters:
    return nominal_dh("ur10", half_pi=math.pi / 2)


def test_ideal_model_closed_form_zero_pose() -> None:
    d1, d4, d5, d6, a2, a3 = 0.1273, 0.163941, 0.1157, 0.0922, -0.612, -0.5723
    T = fk_dh(_ur10_ideal(), np.zeros(6))
    assert T[0, 3] == pytest.approx(a2 + a3, rel=1e-15)
    assert T[1, 3] == pytest.approx(-(d4 + d6), rel=1e-15)
    assert T[2, 3] == pytest.approx(d1 - d5, rel=1e-15)


def test_ideal_model_closed_form_bent_pose() -> None:
    d1, d4, d5, d6, a2, a3 = 0.1273, 0.163941, 0.1157, 0.0922, -0.612, -0.5723
    q = np.array([math.pi / 2, -math.pi / 4, math.pi / 2, -math.pi / 4, 0, 0])
    T = fk_dh(_ur10_ideal(), q)
    r2 = math.sqrt(2)
    expected = (d4 + d6, a2 / r2 + a3 / r2, d1 - a2 / r2 + a3 / r2 - d5)
    np.testing.assert_allclose(T[:3, 3], expected, atol=1e-8)
    # the corrected chain of the ideal model is the unchanged chain (d2 = d3 = 0 → nothing to move)
    np.testing.assert_allclose(chain_fk(_ur10_ideal(), q[None])[0], T, rtol=0, atol=1e-15)


def test_batched_fk_equals_python_loop() -> None:
    dh = nominal_dh("ur5e")
    q = np.random.default_rng(3).uniform(-6, 6, (20, 6))
    T = fk_dh(dh, q, chunk=7)
    for i in range(20):
        np.testing.assert_allclose(T[i], np.array(fk_dh_loop(dh, list(q[i]))), atol=1e-15)


def test_fk_rejects_wrong_shape() -> None:
    with pytest.raises(ShapeMismatchError, match=r"expected \(N, 6\)"):
        fk_dh(nominal_dh("ur5e"), np.zeros((3, 5)))


# --- the correction: upstream calibration_test reproduced ---------------------------------------------------


def test_corrected_chain_equals_dh_fk_1000_random_q(test_set: tuple[int, DHParameters]) -> None:
    set_id, dh = test_set
    q = np.random.default_rng(1000 + set_id).uniform(-2 * math.pi, 2 * math.pi, (1000, 6))
    T_dh = fk_dh(dh, q)
    T_c = chain_fk(dh, q)
    assert np.max(np.abs(T_c[:, :3, 3] - T_dh[:, :3, 3])) < 1e-12
    assert np.max(rotation_angle_between(T_c[:, :3, :3], T_dh[:, :3, :3])) < 1e-12


def test_corrected_d_values_follow_closed_form(test_set: tuple[int, DHParameters]) -> None:
    _, dh = test_set
    chain = correct_chain(dh)
    d2, d3, d4 = dh.d_m[1], dh.d_m[2], dh.d_m[3]
    a2, al2, al3, th2 = dh.a_m[1], dh.alpha_rad[1], dh.alpha_rad[2], dh.theta_rad[1]
    d3p = d3 + d2 / math.cos(al2)
    assert chain[2, 2, 3] == 0.0 and chain[4, 2, 3] == 0.0  # d2' = d3' = 0
    assert chain[6, 2, 3] == pytest.approx(d4 + d3p / math.cos(al3), abs=1e-9)
    assert chain[3, 0, 3] == pytest.approx(-math.hypot(a2, d2 * math.tan(al2)), abs=1e-12)
    theta2p = (
        math.atan2(
            math.sin(th2) * a2 + math.cos(th2) * d2 * math.tan(al2),
            math.cos(th2) * a2 - math.sin(th2) * d2 * math.tan(al2),
        )
        - math.pi
    )
    R = chain[2, :3, :3]
    assert math.atan2(R[1, 0], R[0, 0]) == pytest.approx(
        math.atan2(math.sin(theta2p), math.cos(theta2p)), abs=1e-12
    )


def test_set3_corrected_arm_is_physical(dh_sets: dict[int, DHParameters]) -> None:
    # set 3 has d2 = 439 m; after correction the arm is back to UR10e size and d4 ≈ nominal
    kin = correct_kinematics(dh_sets[3])
    forearm, wrist_1 = kin.links[2], kin.links[3]
    assert forearm.xyz_m[0] == pytest.approx(-0.6125407744492783, abs=1e-12)
    assert wrist_1.xyz_m[0] == pytest.approx(-0.5713541682704182, abs=1e-12)
    assert wrist_1.xyz_m[2] == pytest.approx(0.1745080134426083, abs=1e-12)
    assert kin.hash == "calib_8779175261365510310"


# --- rpy conventions ---------------------------------------------------------------------------------------


def test_ur5e_defaults_regenerated_upstream_values() -> None:
    kin = default_kinematics("ur5e", "upstream")
    links = {lk.name: lk for lk in kin.links}
    assert links["wrist_2"].xyz_m == (0.0, -0.0997, -2.0448811822978515e-11)
    assert links["wrist_3"].rpy_rad == (1.5707963265897931, math.pi, math.pi)
    assert links["shoulder"].xyz_m == (0.0, 0.0, 0.1625)
    assert links["forearm"].xyz_m == (-0.425, 0.0, 0.0)
    assert links["wrist_1"].xyz_m == (-0.3922, 0.0, 0.1333)
    assert links["upper_arm"].rpy_rad == (1.570796327, 0.0, 0.0)
    # URDF mode expresses the same rotation with a pitch in [-π/2, π/2]
    urdf = {lk.name: lk for lk in default_kinematics("ur5e", "urdf").links}
    R_up = matrix_from_rpy_urdf(links["wrist_3"].rpy_rad)
    R_urdf = matrix_from_rpy_urdf(urdf["wrist_3"].rpy_rad)
    assert rotation_angle_between(R_up, R_urdf) < 1e-15
    assert urdf["wrist_3"].rpy_rad[0] == pytest.approx(-1.570796327, abs=1e-15)


@pytest.mark.parametrize("model", sorted(UR_MODELS))
def test_defaults_have_no_negative_zero_and_exact_fk(model: str) -> None:
    for rpy in ("urdf", "upstream"):
        kin = default_kinematics(model, rpy)
        for lk in kin.links:
            for v in (*lk.xyz_m, *lk.rpy_rad):
                assert math.copysign(1.0, v) == 1.0 or v != 0.0
        q = np.random.default_rng(5).uniform(-6, 6, (200, 6))
        T = fk_origins(kin.xyz_array(), kin.rpy_array(), q)
        T_dh = fk_dh(nominal_dh(model), q)
        assert np.max(np.abs(T[:, :3, 3] - T_dh[:, :3, 3])) < 1e-15 * 10


# reference: upstream's Eigen angles read as URDF rpy are off by up to 4.3e-5 m (set 1), 6.6e-6 (2), 3.3e-6 (3)
UPSTREAM_ERROR_BOUNDS = {1: (4.3e-5, 6.3e-5), 2: (6.6e-6, 7.4e-6), 3: (3.3e-6, 3.1e-6)}


def test_upstream_rpy_mode_reproduces_upstream_error_urdf_mode_exact(
    test_set: tuple[int, DHParameters],
) -> None:
    set_id, dh = test_set
    q = np.random.default_rng(7).uniform(-2 * math.pi, 2 * math.pi, (1000, 6))
    T_dh = fk_dh(dh, q)
    up = correct_kinematics(dh, "upstream")
    T_up = fk_origins(up.xyz_array(), up.rpy_array(), q)
    pos_up = np.max(np.linalg.norm(T_up[:, :3, 3] - T_dh[:, :3, 3], axis=1))
    rot_up = np.max(rotation_angle_between(T_up[:, :3, :3], T_dh[:, :3, :3]))
    bound_pos, bound_rot = UPSTREAM_ERROR_BOUNDS[set_id]
    assert bound_pos / 3 < pos_up < bound_pos * 1.05
    assert bound_rot / 1.2 < rot_up < bound_rot * 1.05
    ok = correct_kinematics(dh, "urdf")
    T_ok = fk_origins(ok.xyz_array(), ok.rpy_array(), q)
    assert np.max(np.linalg.norm(T_ok[:, :3, 3] - T_dh[:, :3, 3], axis=1)) <= 1e-10
    assert np.max(rotation_angle_between(T_ok[:, :3, :3], T_dh[:, :3, :3])) <= 1e-10
    # same translations, only the angles differ
    np.testing.assert_array_equal(up.xyz_array(), ok.xyz_array())


def test_set1_upstream_angles_pinned(dh_sets: dict[int, DHParameters]) -> None:
    up = {lk.name: lk.rpy_rad for lk in correct_kinematics(dh_sets[1], "upstream").links}
    # Eigen's eulerAngles(0,1,2) returns the alternate (≈π, ≈π, ≈π) triple for near-identity forearm/wrist_1
    assert up["forearm"] == pytest.approx(
        (3.1343383537539844, 3.1414684740475196, -3.1415039327216476), abs=1e-13
    )
    assert up["wrist_1"] == pytest.approx(
        (3.128129279851486, 3.140861213894874, -3.141584670903837), abs=1e-13
    )
    assert up["wrist_3"][1] == math.pi


def test_eigen_euler_is_intrinsic_xyz() -> None:
    rng = np.random.default_rng(11)
    for _ in range(50):
        a = rng.uniform(-3, 3, 3)
        R = rot_x(a[0]) @ rot_y(a[1]) @ rot_z(a[2])
        r0, r1, r2 = eigen_euler_xyz(R)
        assert 0.0 <= r0 <= math.pi
        np.testing.assert_allclose(rot_x(r0) @ rot_y(r1) @ rot_z(r2), R, atol=1e-14)


@given(
    st.floats(-math.pi, math.pi),
    st.floats(-math.pi / 2 + 1e-3, math.pi / 2 - 1e-3),
    st.floats(-math.pi, math.pi),
)
def test_urdf_rpy_round_trip(roll: float, pitch: float, yaw: float) -> None:
    R = rot_z(yaw) @ rot_y(pitch) @ rot_x(roll)
    rpy = rpy_urdf_from_matrix(R)
    np.testing.assert_allclose(matrix_from_rpy_urdf(rpy), R, atol=1e-14)
    assert rotation_angle_between(matrix_from_rpy_urdf(rpy), R) < 1e-14


# --- degenerate inputs ---------------------------------------------------------------------------------------


def _ur10e_with(**changes: tuple[float, ...]) -> DHParameters:
    base = nominal_dh("ur10e")
    fields = {"theta_rad": base.theta_rad, "a_m": base.a_m, "d_m": base.d_m, "alpha_rad": base.alpha_rad}
    fields.update(changes)
    return DHParameters(**fields)


def _assert_exact(dh: DHParameters) -> None:
    q = np.random.default_rng(9).uniform(-2 * math.pi, 2 * math.pi, (300, 6))
    T_dh = fk_dh(dh, q)
    for rpy in ("urdf",):
        kin = correct_kinematics(dh, rpy)
        T = fk_origins(kin.xyz_array(), kin.rpy_array(), q)
        assert np.all(np.isfinite(kin.xyz_array())) and np.all(np.isfinite(kin.rpy_array()))
        assert np.max(np.abs(T[:, :3, 3] - T_dh[:, :3, 3])) < 1e-12
        assert np.max(rotation_angle_between(T[:, :3, :3], T_dh[:, :3, :3])) < 1e-12


def test_next_d_exactly_zero_is_handled_exactly() -> None:
    # upstream normalises a zero vector here and writes NaN (d2 = 0.5, d3 = 0)
    dh = _ur10e_with(
        d_m=(0.1807, 0.5, 0.0, 0.17415, 0.11985, 0.11655), alpha_rad=(PI_2, 0.01, 0.0, PI_2, -PI_2, 0)
    )
    _assert_exact(dh)
    assert correct_chain(dh)[4, 2, 3] == 0.0  # d3 absorbed d2 and was then moved on to joint 4


def test_a_exactly_zero_is_handled_exactly() -> None:
    # upstream omits the −π when a == 0 and lands 2‖I‖ (2 cm) away: a2 = 0, d2 = 1, α2 = 0.01
    dh = _ur10e_with(
        a_m=(0, 0.0, -0.57155, 0, 0, 0),
        d_m=(0.1807, 1.0, -1.0, 0.17415, 0.11985, 0.11655),
        alpha_rad=(PI_2, 0.01, 0.0, PI_2, -PI_2, 0),
    )
    _assert_exact(dh)


def test_negative_cos_alpha_is_handled_exactly() -> None:
    # upstream corrects d with the wrong sign when |α| > π/2
    dh = _ur10e_with(
        d_m=(0.1807, 0.3, -0.2, 0.17415, 0.11985, 0.11655),
        alpha_rad=(PI_2, math.pi - 0.05, 0.02, PI_2, -PI_2, 0),
    )
    _assert_exact(dh)
    assert correct_chain(dh)[4, 2, 3] == 0.0


def test_seed_exaggerated_example_is_exact() -> None:
    dh = DHParameters(
        theta_rad=(0,) * 6,
        a_m=(0, -0.6127, -0.57155, 0, 0, 0),
        d_m=(0.1807, 1, 0.5, -1.32585, 0.11985, 0.11655),
        alpha_rad=(PI_2, 0.2, 0, PI_2, -PI_2, 0),
    )
    _assert_exact(dh)


@pytest.mark.parametrize("alpha2", [PI_2, -PI_2, math.pi / 2, math.pi / 2 + 1e-4])
def test_alpha_half_pi_is_refused(alpha2: float) -> None:
    dh = _ur10e_with(
        d_m=(0.1807, 0.5, -0.5, 0.17415, 0.11985, 0.11655), alpha_rad=(PI_2, alpha2, 0, PI_2, -PI_2, 0)
    )
    with pytest.raises(InvalidCalibrationError, match=r"DH joint 2: alpha = .* parallel"):
        correct_kinematics(dh)


def test_nan_input_refused() -> None:
    with pytest.raises(InvalidCalibrationError, match=r"DH parameter d\[1\] is nan"):
        _ur10e_with(d_m=(0.1807, math.nan, 0, 0.17415, 0.11985, 0.11655))


def test_unknown_model_and_rpy_refused() -> None:
    with pytest.raises(UsageError, match="unknown UR model 'ur99'"):
        nominal_dh("ur99")
    with pytest.raises(UsageError, match="--rpy 'xyz'"):
        correct_kinematics(nominal_dh("ur5e"), "xyz")


realistic = st.builds(
    lambda model, d2, th2, th3, al2, al3, a2d, small: (model, d2, th2, th3, al2, al3, a2d, small),
    st.sampled_from(sorted(UR_MODELS)),
    st.floats(-500, 500),
    st.floats(-math.pi, math.pi),
    st.floats(-math.pi, math.pi),
    st.floats(-0.02, 0.02),
    st.floats(-0.02, 0.02),
    st.floats(-1.0, 1.0),
    st.lists(st.floats(-1e-3, 1e-3), min_size=12, max_size=12),
)


def make_realistic(params: tuple) -> DHParameters:  # type: ignore[type-arg]
    model, d2, th2, th3, al2, al3, a2d, small = params
    nom = nominal_dh(model)
    deltas = DHParameters(
        theta_rad=(small[0], th2, th3, -(th2 + th3) + small[1], small[2], small[3]),
        a_m=(small[4], a2d, small[5], small[6], small[7], 0.0),
        d_m=(small[8], d2, -d2 + small[9], small[10], small[11], 0.0),
        alpha_rad=(small[0], al2, al3, small[1], small[2], 0.0),
    )
    return nom + deltas


@given(realistic)
def test_hypothesis_realistic_calibrations_correct_exactly(params: tuple) -> None:  # type: ignore[type-arg]
    dh = make_realistic(params)
    q = np.random.default_rng(0).uniform(-2 * math.pi, 2 * math.pi, (50, 6))
    T_dh = fk_dh(dh, q)
    kin = correct_kinematics(dh)
    T = fk_origins(kin.xyz_array(), kin.rpy_array(), q)
    assert np.max(np.abs(T[:, :3, 3] - T_dh[:, :3, 3])) < 1e-10
    assert np.max(rotation_angle_between(T[:, :3, :3], T_dh[:, :3, :3])) < 1e-10


@given(st.lists(st.floats(-1.0, 1.0), min_size=3, max_size=3), st.floats(0.0, math.pi - 1e-6))
def test_rotvec_round_trip(axis: list[float], angle: float) -> None:
    from robocal.core.se3 import matrix_from_rotvec, rotvec_from_matrix

    a = np.array(axis)
    if np.linalg.norm(a) < 1e-3:
        a = np.array([0.0, 0.0, 1.0])
    v = a / np.linalg.norm(a) * angle
    R = matrix_from_rotvec(v)
    np.testing.assert_allclose(R @ R.T, np.eye(3), atol=1e-14)
    np.testing.assert_allclose(rotvec_from_matrix(R), v, atol=1e-9)


@given(st.lists(st.floats(-1.0, 1.0), min_size=3, max_size=3), st.floats(0.0, math.pi))
def test_quaternion_from_matrix_is_the_rotation(axis: list[float], angle: float) -> None:
    from robocal.core.se3 import matrix_from_rotvec, quaternion_from_matrix

    a = np.array(axis)
    if np.linalg.norm(a) < 1e-3:
        a = np.array([1.0, 0.0, 0.0])
    a = a / np.linalg.norm(a)
    w, x, y, z = quaternion_from_matrix(matrix_from_rotvec(a * angle))
    assert w >= 0.0
    assert math.sqrt(w * w + x * x + y * y + z * z) == pytest.approx(1.0, abs=1e-14)
    # q = (cos θ/2, sin θ/2 · axis), the sign fixed by w ≥ 0 (at θ = π, w = 0 and either sign is the rotation)
    expected = np.array([math.cos(angle / 2), *(math.sin(angle / 2) * a)])
    got = np.array([w, x, y, z])
    assert min(np.abs(got - expected).max(), np.abs(got + expected).max()) < 1e-12


def test_quaternion_from_matrix_golden() -> None:
    from robocal.core.se3 import quaternion_from_matrix, rot_z

    w, x, y, z = quaternion_from_matrix(rot_z(math.pi / 2))  # 90° about z: (cos 45°, 0, 0, sin 45°)
    assert (w, x, y, z) == pytest.approx((math.sqrt(0.5), 0.0, 0.0, math.sqrt(0.5)), abs=1e-15)
    assert quaternion_from_matrix(np.diag([1.0, -1.0, -1.0])) == (0.0, 1.0, 0.0, 0.0)  # 180° about x


def test_negative_zero_in_raw_dh_is_hashed_like_the_driver() -> None:
    # the driver prints the controller's raw doubles with ostream <<, so -0.0 hashes as "-0"
    nom = nominal_dh("ur5e")
    a_raw = (*nom.a_m[:5], -0.0)
    dh = DHParameters(nom.theta_rad, a_raw, nom.d_m, nom.alpha_rad)
    assert math.copysign(1.0, dh.a_m[5]) == -1.0
    assert kinematics_hash_string(dh.theta_rad, dh.d_m, dh.a_m, dh.alpha_rad).endswith("0.0996-00")
    expected = calib_hash(nom.theta_rad, nom.d_m, a_raw, nom.alpha_rad)
    assert expected != "calib_12788084448423163542"
    assert correct_kinematics(dh).hash == expected
    # the same through the wire format
    info, _ = parse_kinematics_info(encode_kinematics_info(dh))
    assert correct_kinematics(info.dh).hash == expected
    # the written file still never contains -0
    assert ": -0.0\n" not in kinematics_to_text(correct_kinematics(dh))


def test_rotations_are_exactly_the_textbook_matrices() -> None:
    from robocal.core.se3 import rot_x, rot_y, rot_z

    a = 0.3
    c, s = math.cos(a), math.sin(a)
    assert rot_x(a).tolist() == [[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]]
    assert rot_y(a).tolist() == [[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]]
    assert rot_z(a).tolist() == [[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]]
    assert rot_z(np.zeros((2, 5))).shape == (2, 5, 3, 3)


def test_huge_next_d_is_corrected_not_a_zero_division() -> None:
    # d3 = 1e300: |d3·u|² overflowed, the normalised axis became 0 and the division raised ZeroDivisionError
    n = nominal_dh("ur10e")
    dh = DHParameters(
        n.theta_rad,
        n.a_m,
        (0.1807, 1.0, 1e300, 0.17415, 0.11985, 0.11655),
        (1.570796327, 0.01, 0.0, 1.570796327, -1.570796327, 0.0),
    )
    kin = correct_kinematics(dh)
    forearm = kin.links[2]
    assert forearm.xyz_m[0] == pytest.approx(-math.hypot(-0.6127, math.tan(0.01)), abs=1e-15)
    assert kin.links[3].xyz_m[2] == 1e300


def test_deviation_of_absurd_lengths_does_not_overflow() -> None:
    import warnings

    from robocal.core.ur import deviation_from_nominal

    n = nominal_dh("ur10e")
    kin = correct_kinematics(
        DHParameters(n.theta_rad, (0.0, -1e300, -0.5, 0.0, 0.0, 0.0), n.d_m, n.alpha_rad)
    )
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # numpy's overflow RuntimeWarning would print on the CLI's stderr
        dev = deviation_from_nominal(kin)
    assert dev.length_m == 1e300 and dev.length_field == "a2"
