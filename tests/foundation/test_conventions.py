from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from robocal.core import RobotCalibration
from robocal.core.conventions import (
    LEROBOT_LEGACY_RAD_PER_TICK,
    berkeley_offset_from_homing,
    homing_from_berkeley_offset,
    homing_from_joint_frame_offset,
    homing_from_lerobot_legacy,
    homing_from_transmission,
    joint_frame_offset_from_homing,
    lerobot_legacy_from_homing,
    transmission_from_homing,
)

directions = st.sampled_from([-1.0, 1.0])
offsets = st.floats(-20.0, 20.0, allow_nan=False)
raws = st.floats(-50.0, 50.0, allow_nan=False)


def canonical(d: float, h: float, raw: float) -> float:
    return d * (raw - h)


def test_worked_example_left_elbow() -> None:
    # direction -1, homing offset 1.0 rad (the seed's worked example)
    assert berkeley_offset_from_homing(-1, 1.0) == -1.0
    n, off = transmission_from_homing(-1, 1.0)
    assert (n, off) == (-1.0, 1.0)
    assert joint_frame_offset_from_homing(-1, 1.0) == 1.0


@given(directions, offsets, raws)
def test_berkeley_same_joint_position_and_exact_inverse(d: float, h: float, raw: float) -> None:
    off = berkeley_offset_from_homing(d, h)
    q_berkeley = raw * d - off  # Berkeley-Lowlevel read formula
    assert q_berkeley == pytest.approx(canonical(d, h, raw), abs=1e-12)
    assert homing_from_berkeley_offset(d, off) == h  # exact: multiplication by ±1


@given(directions, offsets, raws)
def test_simple_transmission_same_joint_position_and_exact_inverse(d: float, h: float, raw: float) -> None:
    n, off = transmission_from_homing(d, h)
    q_transmission = raw / n + off  # SimpleTransmission actuator -> joint
    assert q_transmission == pytest.approx(canonical(d, h, raw), abs=1e-12)
    d2, h2 = homing_from_transmission(n, off)
    assert d2 == d
    assert h2 == h


@given(directions, offsets, raws)
def test_joint_frame_offset_form(d: float, h: float, raw: float) -> None:
    off = joint_frame_offset_from_homing(d, h)
    assert d * raw + off == pytest.approx(canonical(d, h, raw), abs=1e-12)
    assert homing_from_joint_frame_offset(d, off) == h


@given(st.sampled_from([0, 1]), st.integers(-8192, 8192), st.integers(-8192, 8192))
def test_lerobot_legacy_degree_exact(drive_mode: int, h: int, raw: int) -> None:
    s = -1 if drive_mode else 1
    deg_legacy = (s * raw + h) / 2048 * 180  # LeRobot legacy apply_calibration, DEGREE mode
    d, hc, scale = homing_from_lerobot_legacy(drive_mode, h)
    cal = RobotCalibration(["j"], [float(d)], [float(hc)], [float(scale)])
    q_rad = float(cal.to_joint(np.array([raw]))[0])
    assert math.degrees(q_rad) == pytest.approx(deg_legacy, abs=1e-9)
    dm2, h2 = lerobot_legacy_from_homing(d, hc)
    assert int(dm2) == drive_mode
    assert float(h2) == h


def test_lerobot_legacy_golden_vectors() -> None:
    # homing_offset [2048, -1024, 0], drive_mode [1, 0, 0]: raw [1024, 2048, 1024] -> 90 degrees each
    d, h, s = homing_from_lerobot_legacy([1, 0, 0], [2048, -1024, 0])
    cal = RobotCalibration(["a", "b", "c"], d, h, s)
    np.testing.assert_allclose(np.degrees(cal.to_joint([1024, 2048, 1024])), [90.0, 90.0, 90.0], atol=1e-12)
    np.testing.assert_allclose(
        np.degrees(cal.to_joint([3072, 3072, -2048])), [-90.0, 180.0, -180.0], atol=1e-12
    )
    assert math.pi / 2048 == LEROBOT_LEGACY_RAD_PER_TICK
