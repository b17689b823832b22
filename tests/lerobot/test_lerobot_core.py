"""Golden vectors (LeRobot 0.6.1 and legacy 59e275743 outputs) and properties of robocal.core.lerobot."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from robocal.core import lerobot as core
from robocal.core.wrap_range import RangeTracker
from robocal.errors import InvalidCalibrationError, JointOutOfRangeError, ShapeMismatchError
from robocal.lerobot import MotorCalibration, NormMode, normalize, unnormalize

CAL = MotorCalibration(id=1, drive_mode=0, homing_offset=0, range_min=1000, range_max=3000)
CAL_DM = MotorCalibration(id=1, drive_mode=1, homing_offset=0, range_min=1000, range_max=3000)
RAWS = [500, 1000, 1500, 2000, 2001, 2500, 3000, 3500]


# ------------------------------------------------------------------------------------------ §4.1 normalize
@pytest.mark.parametrize(
    ("cal", "mode", "expected"),
    [
        (CAL, "range_m100_100", [-100, -100, -50, 0, 0.1, 50, 100, 100]),
        (CAL_DM, "range_m100_100", [100, 100, 50, -0.0, -0.1, -50, -100, -100]),
        (CAL, "range_0_100", [0, 0, 25, 50, 50.05, 75, 100, 100]),
        (CAL_DM, "range_0_100", [100, 100, 75, 50, 49.95, 25, 0, 0]),
    ],
)
def test_normalize_range_golden(cal: MotorCalibration, mode: str, expected: list[float]) -> None:
    out = normalize(RAWS, cal, mode)
    np.testing.assert_allclose(out, expected, rtol=0, atol=1e-9)


def test_normalize_m100_dm1_gives_negative_zero_like_lerobot() -> None:
    assert math.copysign(1.0, float(normalize(2000, CAL_DM, "range_m100_100"))) == -1.0


@pytest.mark.parametrize("cal", [CAL, CAL_DM])
def test_normalize_degrees_golden_ignores_drive_mode(cal: MotorCalibration) -> None:
    out = normalize(RAWS, cal, NormMode.DEGREES)
    expected = [-131.868132, -87.912088, -43.956044, 0, 0.087912, 43.956044, 87.912088, 131.868132]
    np.testing.assert_allclose(out, expected, atol=5e-7)


# ---------------------------------------------------------------------------------------- §4.2 unnormalize
@pytest.mark.parametrize(
    ("cal", "mode", "pairs"),
    [
        (
            CAL,
            "range_m100_100",
            [
                (-150, 1000),
                (-100, 1000),
                (-50, 1500),
                (0, 2000),
                (0.1, 2001),
                (33.3, 2333),
                (50, 2500),
                (100, 3000),
                (150, 3000),
            ],
        ),
        (
            CAL_DM,
            "range_m100_100",
            [(-150, 3000), (-50, 2500), (0, 2000), (0.1, 1999), (33.3, 1667), (100, 1000)],
        ),
        (CAL, "range_0_100", [(-10, 1000), (25, 1500), (50, 2000), (50.05, 2001), (75, 2500), (110, 3000)]),
        (CAL_DM, "range_0_100", [(-10, 3000), (25, 2500), (50.05, 1999), (75, 1500), (110, 1000)]),
        (
            CAL,
            "degrees",
            [
                (-200, -275),
                (-90, 976),
                (-45, 1488),
                (0, 2000),
                (0.1, 2001),
                (45, 2511),
                (90, 3023),
                (200, 4275),
            ],
        ),
        (CAL_DM, "degrees", [(-200, -275), (-90, 976), (0, 2000), (200, 4275)]),
        (CAL, "range_m100_100", [(0.09, 2000), (0.0999, 2000), (0.1, 2001), (-0.09, 1999), (99.99, 2999)]),
        (CAL, "degrees", [(-0.05, 1999), (-0.1, 1998)]),
    ],
)
def test_unnormalize_golden(cal: MotorCalibration, mode: str, pairs: list[tuple[float, int]]) -> None:
    values = [p[0] for p in pairs]
    assert unnormalize(values, cal, mode).tolist() == [p[1] for p in pairs]


def test_full_range_and_dynamixel_vectors() -> None:
    full = MotorCalibration(1, 0, 0, 0, 4095)
    np.testing.assert_allclose(
        normalize([2047, 2048], full, "range_m100_100"), [-0.02442, 0.02442], atol=5e-6
    )
    for dm in (0, 1):
        cal = MotorCalibration(1, dm, 0, 1000, 3000)
        assert float(normalize(1500, cal, "range_m100_100", apply_drive_mode=False)) == -50.0
        assert float(normalize(1500, cal, "range_0_100", apply_drive_mode=False)) == 25.0


def test_feetech_register_read_and_write_path() -> None:
    # register 0x05DC -> 1500 -> -50.0; register 0x8005 -> -5 -> clamped to -100.0
    assert float(normalize(core.decode_sign_magnitude(0x05DC, 15), CAL, "range_m100_100")) == -50.0
    assert core.decode_sign_magnitude(0x8005, 15) == -5
    assert float(normalize(-5, CAL, "range_m100_100")) == -100.0
    goal = int(unnormalize(-200.0, CAL, "degrees"))
    assert goal == -275 and core.encode_sign_magnitude(goal, 15) == 33043 == 0x8113


def test_vector_shapes_and_mixed_modes() -> None:
    cals = [CAL, CAL_DM, MotorCalibration(3, 0, 0, 0, 4095)]
    raw = np.array([[1500, 1500, 2047], [3000, 1000, 4095]])
    out = normalize(raw, cals, ["range_m100_100", "range_0_100", "degrees"])
    assert out.shape == (2, 3)
    np.testing.assert_allclose(out[:, 0], [-50, 100])
    np.testing.assert_allclose(out[:, 1], [75, 100])
    assert out[1, 2] == pytest.approx((4095 - 2047.5) * 360 / 4095)
    modes = ["range_m100_100", "range_0_100", "degrees"]
    exact = normalize(raw, cals, modes, compat="exact")
    assert unnormalize(exact, cals, modes, compat="exact").tolist() == raw.tolist()
    assert normalize(np.full((4, 5), 1500), CAL, "range_m100_100").shape == (4, 5)


def _lerobot_normalize(val: int, lo: int, hi: int, dm: bool, mode: str) -> float:
    # Transcription of LeRobot 0.6.1 MotorsBus._normalize for one motor (Python floats).
    if mode == "range_m100_100":
        b = min(hi, max(lo, val))
        n = (((b - lo) / (hi - lo)) * 200) - 100
        return -n if dm else n
    if mode == "range_0_100":
        b = min(hi, max(lo, val))
        n = ((b - lo) / (hi - lo)) * 100
        return 100 - n if dm else n
    mid = (lo + hi) / 2
    return (val - mid) * 360 / 4095


def _lerobot_unnormalize(val: float, lo: int, hi: int, dm: bool, mode: str) -> int:
    if mode == "range_m100_100":
        val = -val if dm else val
        b = min(100.0, max(-100.0, val))
        return int(((b + 100) / 200) * (hi - lo) + lo)
    if mode == "range_0_100":
        val = 100 - val if dm else val
        b = min(100.0, max(0.0, val))
        return int((b / 100) * (hi - lo) + lo)
    mid = (lo + hi) / 2
    return int((val * 4095 / 360) + mid)


@given(
    lo=st.integers(0, 4000),
    width=st.integers(1, 4095),
    dm=st.booleans(),
    mode=st.sampled_from(["range_m100_100", "range_0_100", "degrees"]),
    data=st.data(),
)
def test_lerobot_compat_is_bit_identical(
    lo: int, width: int, dm: bool, mode: str, data: st.DataObject
) -> None:
    hi = min(4095, lo + width)
    if hi == lo:
        lo -= 1
    cal = MotorCalibration(1, int(dm), 0, lo, hi)
    raws = data.draw(st.lists(st.integers(-100, 4200), min_size=1, max_size=20))
    out = normalize(raws, cal, mode)
    ref = [_lerobot_normalize(r, lo, hi, dm, mode) for r in raws]
    assert [float(v).hex() for v in out] == [v.hex() for v in ref]
    vals = data.draw(st.lists(st.floats(-250, 250, allow_nan=False), min_size=1, max_size=20))
    assert unnormalize(vals, cal, mode).tolist() == [_lerobot_unnormalize(v, lo, hi, dm, mode) for v in vals]


# -------------------------------------------------------------------------------------- §4.3 round trips
def _round_trip_failures(lo: int, hi: int, dm: int, mode: str, compat: str) -> int:
    cal = MotorCalibration(1, dm, 0, lo, hi)
    raws = np.arange(lo, hi + 1)
    back = unnormalize(normalize(raws, cal, mode, compat=compat), cal, mode, compat=compat)  # type: ignore[arg-type]
    return int(np.count_nonzero(back != raws))


def test_lerobot_round_trip_loss_counts() -> None:
    assert _round_trip_failures(1000, 3000, 1, "range_0_100", "lerobot") == 14
    assert _round_trip_failures(1000, 3000, 0, "range_0_100", "lerobot") == 0
    assert _round_trip_failures(1000, 3000, 0, "range_m100_100", "lerobot") == 0
    assert _round_trip_failures(0, 4095, 0, "range_m100_100", "lerobot") == 726
    assert _round_trip_failures(43, 1335, 0, "range_m100_100", "lerobot") == 185
    assert _round_trip_failures(27, 3608, 0, "range_m100_100", "lerobot") == 545
    assert _round_trip_failures(145, 3999, 0, "range_m100_100", "lerobot") == 466
    assert _round_trip_failures(0, 4095, 0, "range_0_100", "lerobot") == 511
    assert _round_trip_failures(0, 4095, 1, "range_0_100", "lerobot") == 943
    cal = MotorCalibration(1, 1, 0, 1000, 3000)
    assert float(normalize(1564, cal, "range_0_100")) == 71.80000000000001
    assert int(unnormalize(71.80000000000001, cal, "range_0_100")) == 1563
    full = MotorCalibration(1, 0, 0, 0, 4095)
    assert int(unnormalize(normalize(1, full, "range_m100_100"), full, "range_m100_100")) == 0
    assert int(unnormalize(normalize(15, full, "range_0_100"), full, "range_0_100")) == 14


@given(
    lo=st.integers(-2048, 4000),
    width=st.integers(1, 4095),
    dm=st.integers(0, 1),
    dm_hw=st.booleans(),
    mode=st.sampled_from(list(NormMode)),
    data=st.data(),
)
def test_exact_round_trip_is_lossless(
    lo: int, width: int, dm: int, dm_hw: bool, mode: NormMode, data: st.DataObject
) -> None:
    cal = MotorCalibration(7, dm, 0, lo, lo + width)
    raws = np.array(data.draw(st.lists(st.integers(lo, lo + width), min_size=1, max_size=50)))
    norm = normalize(raws, cal, mode, apply_drive_mode=dm_hw, compat="exact")
    assert unnormalize(norm, cal, mode, apply_drive_mode=dm_hw, compat="exact").tolist() == raws.tolist()


def test_physical_convention_degrees_uses_4096_and_drive_mode() -> None:
    # This used to be compat="exact"; exact now changes rounding only (issue #9), the physical scale and sign
    # are the separate, explicitly named convention="physical".
    assert float(normalize(3000, CAL, "degrees", convention="physical")) == 1000 * 360 / 4096
    assert float(normalize(3000, CAL_DM, "degrees", convention="physical")) == -1000 * 360 / 4096
    for compat in ("lerobot", "exact"):
        assert (
            float(normalize(3000, CAL_DM, "degrees", compat=compat, convention="physical"))
            == -1000 * 360 / 4096
        )
        assert (
            unnormalize(-1000 * 360 / 4096, CAL_DM, "degrees", compat=compat, convention="physical") == 3000
        )


# ----------------------------------------------------------------------------------------- §4.4 homing
@pytest.mark.parametrize(
    ("pos", "feetech", "fe_reg", "dxl", "dxl_reg"),
    [
        (1337, -710, 2758, 710, 710),
        (42, -2005, 4053, 2005, 2005),
        (3672, 1625, 1625, -1625, 4294965671),
        (0, -2047, 4095, 2047, 2047),
        (2047, 0, 0, 0, 0),
    ],
)
def test_half_turn_homing_golden(pos: int, feetech: int, fe_reg: int, dxl: int, dxl_reg: int) -> None:
    off = core.half_turn_homing_offset(pos, vendor="feetech", compat="lerobot")
    assert off == feetech and core.encode_sign_magnitude(off, 11) == fe_reg
    assert core.half_turn_homing_offset(pos, vendor="feetech") == feetech
    d = core.half_turn_homing_offset(pos, vendor="dynamixel")
    assert d == dxl and core.encode_twos_complement(d, 4) == dxl_reg


def test_half_turn_homing_at_4095() -> None:
    with pytest.raises(
        InvalidCalibrationError, match=r"Magnitude 2048 exceeds 2047 \(max for sign_bit_index=11\)"
    ):
        core.half_turn_homing_offset(4095, vendor="feetech", compat="lerobot")
    assert core.half_turn_homing_offset(4095, vendor="feetech") == 2047  # robocal: held pose then reads 2048
    assert core.half_turn_homing_offset(4095 + 4096, vendor="feetech") == 2047  # multi-turn feedback wrapped
    assert core.half_turn_homing_offset(4095, vendor="dynamixel") == -2048
    assert core.encode_twos_complement(-2048, 4) == 4294965248
    assert core.half_turn_homing_offset(700, vendor="feetech", resolution=1024) == 189


# --------------------------------------------------------------------------------------- §4.5 encodings
@pytest.mark.parametrize(
    ("v", "k", "enc"),
    [
        (5, 4, 5),
        (-1, 4, 17),
        (-8, 4, 24),
        (-3, 3, 11),
        (-710, 11, 2758),
        (-2047, 11, 4095),
        (-1, 11, 2049),
        (-5, 15, 32773),
        (-1000, 15, 33768),
    ],
)
def test_sign_magnitude_encode(v: int, k: int, enc: int) -> None:
    assert core.encode_sign_magnitude(v, k) == enc
    assert core.decode_sign_magnitude(enc, k) == v


@pytest.mark.parametrize(
    ("r", "k", "v"), [(2758, 11, -710), (2048, 11, 0), (4095, 11, -2047), (0x8000, 15, 0), (0x0FFF, 15, 4095)]
)
def test_sign_magnitude_decode(r: int, k: int, v: int) -> None:
    assert core.decode_sign_magnitude(r, k) == v


@pytest.mark.parametrize(
    ("v", "k", "mag", "mx"), [(16, 4, 16, 15), (2048, 11, 2048, 2047), (-4096, 11, 4096, 2047)]
)
def test_sign_magnitude_overflow(v: int, k: int, mag: int, mx: int) -> None:
    with pytest.raises(InvalidCalibrationError, match=f"Magnitude {mag} exceeds {mx} "):
        core.encode_sign_magnitude(v, k)


@pytest.mark.parametrize(
    ("v", "n", "enc"),
    [
        (-1, 1, 255),
        (-128, 1, 128),
        (-1, 2, 65535),
        (-32768, 2, 32768),
        (-710, 4, 4294966586),
        (-1, 4, 4294967295),
    ],
)
def test_twos_complement(v: int, n: int, enc: int) -> None:
    assert core.encode_twos_complement(v, n) == enc
    assert core.decode_twos_complement(enc, n) == v


def test_twos_complement_decode_and_errors() -> None:
    assert core.decode_twos_complement(65535, 2) == -1
    assert core.decode_twos_complement(0x80000000, 4) == -2147483648
    for v, n in ((2**31, 4), (128, 1), (-129, 1)):
        with pytest.raises(InvalidCalibrationError, match="out of range for"):
            core.encode_twos_complement(v, n)


@pytest.mark.parametrize("k", [2, 3, 4, 5])
def test_sign_magnitude_exhaustive(k: int) -> None:
    for v in range(-(2**k) + 1, 2**k):
        assert core.decode_sign_magnitude(core.encode_sign_magnitude(v, k), k) == v


# ------------------------------------------------------------------------------------ §4.6 range tracking
def test_range_tracker_lerobot_fixture_and_seam() -> None:
    tr = RangeTracker(3, period=4096, units="ticks")
    for reading in ([351, 28, 4002], [42, 3600, 2999], [1337, 2444, 146]):
        tr.update(reading)
    assert tr.raw_minimum.tolist() == [42, 28, 146]
    assert tr.raw_maximum.tolist() == [1337, 3600, 4002]
    seam = RangeTracker(1, period=4096, units="ticks")
    for t in (4000, 4050, 4090, 20, 100, 60, 3990):
        seam.update([t])
    assert (seam.raw_minimum[0], seam.raw_maximum[0]) == (20, 4090)  # LeRobot's clipped answer
    assert (int(seam.minimum[0]), int(seam.maximum[0])) == (3990, 4196)  # crossed the seam, not a full turn
    shift, lo, hi = core.centre_homing(3990, 4196)
    assert (shift, lo, hi) == (2046, 1944, 2150)


# ------------------------------------------------------------------------------------------ §4.7 legacy
H = [2048, -1024, 0]
DM = [1, 0, 0]
LEG = core.LegacyCalibration(["a", "b", "c"], H, DM, [0, 0, 0], [1, 1, 1], ["DEGREE"] * 3)


@pytest.mark.parametrize(
    ("raw", "deg"),
    [
        ([2048, 1024, 0], [0.0, 0.0, 0.0]),
        ([1024, 2048, 1024], [90.0, 90.0, 90.0]),
        ([3072, 3072, -2048], [-90.0, 180.0, -180.0]),
        ([0, 4096, 2047], [180.0, 270.0, 179.912109]),
    ],
)
def test_legacy_degree_apply_revert(raw: list[int], deg: list[float]) -> None:
    out = core.apply_legacy(raw, LEG)
    np.testing.assert_allclose(out, deg, atol=5e-7)
    assert core.revert_legacy(out, LEG).tolist() == raw


def test_legacy_degree_out_of_range_message() -> None:
    with pytest.raises(JointOutOfRangeError) as exc:
        core.apply_legacy([0, 5000, 0], LEG)
    msg = str(exc.value)
    assert msg.startswith(
        "Wrong motor position range detected for b. Expected to be in nominal range of [-180, 180]"
    )
    assert (
        "with a maximum range of [-270, 270] degrees" in msg and "present value is 349.453125 degree" in msg
    )
    assert msg.endswith("`python lerobot/scripts/control_robot.py calibrate`")


def test_legacy_revert_rounding_half_to_even() -> None:
    one = core.LegacyCalibration(["m"], [0], [0], [0], [1], ["DEGREE"])
    vals = [[0.0439453125], [0.1318359375], [-0.0439453125], [45.0]]
    assert core.revert_legacy(vals, one).ravel().tolist() == [0, 2, 0, 512]
    inv = core.LegacyCalibration(["m"], [2048], [1], [0], [1], ["DEGREE"])
    assert core.revert_legacy([[0], [90], [-90], [180]], inv).ravel().tolist() == [2048, 1024, 3072, 0]


def test_legacy_linear() -> None:
    lin = core.LegacyCalibration(["gripper"], [0], [0], [2499], [3144], ["LINEAR"])
    out = core.apply_legacy([[2499], [3144], [2821], [2435], [3208]], lin).ravel()
    np.testing.assert_allclose(out, [0.0, 100.0, 49.922482, -9.922481, 109.922478], atol=5e-6)
    assert core.revert_legacy(out[:, None], lin).ravel().tolist() == [2499, 3144, 2821, 2435, 3208]
    for raw, shown in ((2400, "-15.3"), (3300, "124.1")):
        with pytest.raises(JointOutOfRangeError, match=f"present value is {shown}"):
            core.apply_legacy([raw], lin)
    same = core.LegacyCalibration(["gripper"], [0], [0], [2000], [2000], ["LINEAR"])
    with pytest.raises(JointOutOfRangeError, match=r"\[0, 100\] % .*present value is inf %"):
        core.apply_legacy([2100], same)


def test_legacy_calibration_from_poses() -> None:
    names = ["shoulder_pan", "shoulder_lift", "elbow_flex", "wrist_flex", "wrist_roll", "gripper"]
    zero = [2048, 1000, 3100, 2000, 1020, 2040]
    rot = [3080, 2010, 2060, 3050, 2030, 3070]
    d = core.legacy_calibration_from_poses(names, zero, rot, vendor="dynamixel")
    assert d.drive_mode.tolist() == [0, 0, 1, 0, 0, 0]
    assert d.homing_offset.tolist() == [-2048, -1024, 3072, -2048, -1024, -2048]
    assert d.start_pos.tolist() == zero and d.end_pos.tolist() == [3080, 2010, -2060, 3050, 2030, 3070]
    assert d.calib_mode == ("DEGREE",) * 6
    f = core.legacy_calibration_from_poses(names, zero, rot, vendor="feetech")
    assert f.drive_mode.tolist() == [0, 0, 1, 0, 0, 0]
    assert f.homing_offset.tolist() == [-2056, -986, 3084, -2026, -1006, -2046]
    assert f.calib_mode[-1] == "LINEAR" and f.calib_mode[:5] == ("DEGREE",) * 5


def test_nearest_rounded_position_and_autocorrect() -> None:
    ins = [511, 512, 513, 1535, 1536, -512, -513, 2047, 3000, 3584]
    assert core.nearest_rounded_position(ins).tolist() == [0, 0, 1024, 1024, 2048, 0, -1024, 2048, 3072, 4096]
    out, fixed = core.autocorrect_legacy([2048, 5120, 0], LEG)
    assert fixed.homing_offset.tolist() == [2048, -5120, 0] and out.tolist() == [0.0, 0.0, 0.0]
    assert LEG.homing_offset.tolist() == H  # input calibration unchanged


def test_avoid_rotation_reset_and_its_flaw() -> None:
    raws = np.array([100, 50, 4090, 4000, 10, 3000])[:, None]
    assert core.avoid_rotation_reset(raws).ravel().tolist() == [100, 50, -6, -96, 10, -1096]
    two_wraps = np.array([0, -4086 + 4096, 4000])[:, None]  # after one wrap the series is at -4086
    out = core.avoid_rotation_reset(np.array([[-4086], [4000]]))
    assert out.ravel().tolist() == [-4086, -96]  # not -4192
    assert two_wraps.shape == (3, 1)


def test_malformed_inputs_raise_specific_errors() -> None:
    with pytest.raises(InvalidCalibrationError, match="min and max are equal"):
        normalize(1, MotorCalibration(1, 0, 0, 5, 5), "range_0_100")
    with pytest.raises(InvalidCalibrationError, match="norm mode 'percent'"):
        normalize(1, CAL, "percent")
    with pytest.raises(ShapeMismatchError, match="2 modes for 3 motors"):
        normalize([1, 2, 3], [CAL, CAL, CAL], ["degrees", "degrees"])
    with pytest.raises(ShapeMismatchError, match=r"expected \(\.\.\., 2\)"):
        normalize([1, 2, 3], [CAL, CAL], "degrees")
    with pytest.raises(InvalidCalibrationError, match="NaN"):
        unnormalize([float("nan")], CAL, "degrees")
    with pytest.raises(InvalidCalibrationError, match=r"MotorCalibration\.range_min is 1\.5"):
        MotorCalibration(1, 0, 0, 1.5, 3)  # type: ignore[arg-type]
    with pytest.raises(InvalidCalibrationError, match="compat 'fast'"):
        normalize(1, CAL, "degrees", compat="fast")  # type: ignore[arg-type]


@given(
    start=st.integers(0, 4095),
    steps=st.lists(st.integers(-2000, 2000), min_size=1, max_size=60),
)
def test_range_tracker_recovers_true_travel(start: int, steps: list[int]) -> None:
    # a continuous physical path observed modulo 4096: the unwrapped extremes equal the path's extremes
    path = np.cumsum([start, *steps])
    tr = RangeTracker(1, period=4096, units="ticks")
    for p in path:
        tr.update([p % 4096])
    assert int(tr.maximum[0] - tr.minimum[0]) == int(path.max() - path.min())
    assert int(tr.minimum[0]) - int(path.min()) == int(path[0] % 4096) - int(path[0])
    if path.max() - path.min() < 4095:
        _shift, lo, hi = core.centre_homing(int(tr.minimum[0]), int(tr.maximum[0]))
        assert 0 <= lo <= hi <= 4095 and abs((lo + hi) // 2 - 2047) <= 1
