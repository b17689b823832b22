"""robocal.core.lerobot.normalisation (via the public facade): edge inputs of normalize / unnormalize."""

from __future__ import annotations

import numpy as np
import pytest

from robocal.errors import InvalidCalibrationError
from robocal.lerobot import MotorCalibration, legacy, normalize, unnormalize

pytestmark = pytest.mark.timeout(60)

CAL = MotorCalibration(id=1, drive_mode=0, homing_offset=0, range_min=1000, range_max=3000)


# ------------------------------------------------------------------------------------------ public API edges
def test_scalar_raw_with_a_one_motor_sequence() -> None:
    out = normalize(1500, [CAL], "range_m100_100")
    assert out.shape == () and float(out) == -50.0
    back = unnormalize(-50.0, [CAL], ["range_m100_100"])
    assert back.shape == () and int(back) == 1500
    one = legacy.LegacyCalibration(["a"], [0], [0], [0], [0], ["DEGREE"])
    deg = legacy.apply_calibration(1024, one)
    assert isinstance(deg, np.ndarray) and deg.shape == () and float(deg) == 90.0
    ticks = legacy.revert_calibration(90.0, one)
    assert isinstance(ticks, np.ndarray) and ticks.shape == () and int(ticks) == 1024


def test_calibration_mapping_is_taken_in_order() -> None:
    cals = {"a": CAL, "b": MotorCalibration(2, 1, 0, 1000, 3000)}
    np.testing.assert_array_equal(normalize([1500, 1500], cals, "range_m100_100"), [-50.0, 50.0])


@pytest.mark.parametrize("mode", [None, 2, 2.0, b"degrees", [None]])
def test_bad_mode_types_are_calib_errors(mode: object) -> None:
    with pytest.raises(InvalidCalibrationError, match="norm mode"):
        normalize(1500, CAL, mode)  # type: ignore[arg-type]
    with pytest.raises(InvalidCalibrationError, match="norm mode"):
        unnormalize(0.0, CAL, mode)  # type: ignore[arg-type]


@pytest.mark.parametrize("raw", ["abc", 1 + 2j, [[1, 2], [3]], {"a": 1}])
def test_non_numeric_raw_is_a_calib_error(raw: object) -> None:
    with pytest.raises(InvalidCalibrationError, match="raw"):
        normalize(raw, CAL, "degrees")  # type: ignore[arg-type]
    with pytest.raises(InvalidCalibrationError, match="values"):
        unnormalize(raw, CAL, "degrees")  # type: ignore[arg-type]


@pytest.mark.parametrize("compat", ["lerobot", "exact"])
def test_unnormalize_beyond_int64_raises_instead_of_wrapping(compat: str) -> None:
    with pytest.raises(InvalidCalibrationError, match="int64"):
        unnormalize(1e300, CAL, "degrees", compat=compat)  # type: ignore[arg-type]
    assert int(unnormalize(1e300, CAL, "range_m100_100", compat=compat)) == 3000  # clamped: fine  # type: ignore[arg-type]
    one = legacy.LegacyCalibration(["a"], [0], [0], [0], [0], ["DEGREE"])
    with pytest.raises(InvalidCalibrationError, match="int64"):
        legacy.revert_calibration([1e300], one)


@pytest.mark.parametrize("resolution", [0, 1, -4096])
def test_bad_resolution_is_refused(resolution: int) -> None:
    with pytest.raises(InvalidCalibrationError, match="resolution"):
        normalize(1500, CAL, "degrees", resolution=resolution)
    with pytest.raises(InvalidCalibrationError, match="resolution"):
        unnormalize(0.0, CAL, "degrees", resolution=resolution)
