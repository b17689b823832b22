"""``dataset recalibrate --physical``: the physical degree convention is its own option (issue #9)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from dataset_testutil import HI, HOMING_A, HOMING_B, LO, RANGE_A, RANGE_B, all_values, cals

from robocal.cli.main import main
from robocal.dataset import SO_ARM_JOINTS, generate_dataset
from robocal.dataset.lerobot import LeRobotConvention, preset_modes
from robocal.lerobot import write_calibration

DRIVE = [0, 0, 1, 0, 0, 0]  # elbow_flex inverted (Feetech drive_mode 1)


def conv(homing: list[int], ranges: list[tuple[int, int]], convention: str) -> LeRobotConvention:
    modes = preset_modes("so101_follower", SO_ARM_JOINTS)
    return LeRobotConvention.from_calibrations(
        cals(homing, ranges, DRIVE), modes, "feetech", "lerobot", convention
    )  # type: ignore[arg-type]


def test_recalibrate_physical_dataset_with_physical_flag(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    write_calibration(tmp_path / "a.json", cals(HOMING_A, RANGE_A, DRIVE))
    write_calibration(tmp_path / "b.json", cals(HOMING_B, RANGE_B, DRIVE))
    kw = {"n_episodes": 2, "frames_per_episode": 40, "actual_lo": LO, "actual_hi": HI}
    generate_dataset(tmp_path / "src", convention=conv(HOMING_A, RANGE_A, "physical"), **kw)  # type: ignore[arg-type]
    generate_dataset(tmp_path / "rec_b", convention=conv(HOMING_B, RANGE_B, "physical"), **kw)  # type: ignore[arg-type]
    args = ["dataset", "recalibrate", str(tmp_path / "src")]
    common = [
        "--old",
        str(tmp_path / "a.json"),
        "--new",
        str(tmp_path / "b.json"),
        "--robot",
        "so101_follower",
    ]
    assert main([*args, str(tmp_path / "b"), *common, "--physical"]) == 0
    assert main([*args, str(tmp_path / "b_lerobot"), *common]) in (0, 1)
    capsys.readouterr()
    for key in ("observation.state", "action"):
        want = all_values(tmp_path / "rec_b", key)
        np.testing.assert_array_equal(
            all_values(tmp_path / "b", key), want
        )  # what a physical recording gives
        got = all_values(tmp_path / "b_lerobot", key)
        assert not np.array_equal(got, want)  # read as LeRobot's degrees instead: not the same values
    # --compat exact is rounding only: on recorded readings it gives exactly what --compat lerobot gives
    assert main([*args, str(tmp_path / "b_exact"), *common, "--physical", "--compat", "exact"]) == 0
    for key in ("observation.state", "action"):
        np.testing.assert_array_equal(all_values(tmp_path / "b_exact", key), all_values(tmp_path / "b", key))
