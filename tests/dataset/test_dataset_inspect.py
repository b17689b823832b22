from __future__ import annotations

from pathlib import Path

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq
import pytest
from dataset_testutil import (
    HOMING_A,
    RANGE_A,
    A,
    column,
    lekiwi_conv,
)
from tests.parquet import reads_null_list_rows

from robocal.dataset import (
    SO_ARM_JOINTS,
    generate_dataset,
    inspect_dataset,
)
from robocal.dataset.lerobot import LeRobotConvention, preset_modes
from robocal.errors import FileFormatError
from robocal.lerobot import MotorCalibration

MODES = preset_modes("so101_follower", SO_ARM_JOINTS)


def conv(wrist_roll_homing: int) -> LeRobotConvention:
    cals = {n: MotorCalibration(i + 1, 0, 0, 1000, 3000) for i, n in enumerate(SO_ARM_JOINTS)}
    cals["wrist_roll"] = MotorCalibration(5, 0, wrist_roll_homing, 0, 4095)
    return LeRobotConvention.from_calibrations(cals, MODES, "feetech")


def test_full_turn_jump_flagged(tmp_path: Path) -> None:
    # wrist_roll travels over actual ticks 200..3900; a homing offset of 1500 puts the 0/4095 seam at actual
    # 1500, inside the travel, so the stored degrees jump by about 360° whenever the joint crosses it.
    bad, good = conv(1500), conv(0)
    lo = [1100, 1100, 1100, 1100, 200, 1100]
    hi = [2900, 2900, 2900, 2900, 3900, 2900]
    generate_dataset(
        tmp_path / "bad", n_episodes=2, frames_per_episode=300, convention=bad, actual_lo=lo, actual_hi=hi
    )
    generate_dataset(
        tmp_path / "good", n_episodes=2, frames_per_episode=300, convention=good, actual_lo=lo, actual_hi=hi
    )
    rep = inspect_dataset(tmp_path / "bad", calibration=bad, features=["observation.state"])
    flagged = {j.joint for j in rep.flagged}
    assert flagged == {"wrist_roll"}
    roll = next(j for j in rep.joints if j.joint == "wrist_roll")
    assert roll.jumps >= 1 and roll.out_of_range == 0
    assert roll.max - roll.min > 300.0
    ok = inspect_dataset(tmp_path / "good", calibration=good)
    assert ok.flagged == ()
    assert ok.frames == 600
    pan = next(j for j in ok.joints if j.joint == "shoulder_pan" and j.feature == "action")
    assert pan.range_lo == pytest.approx(-1000 * 360 / 4095)
    assert pan.range_hi == pytest.approx(1000 * 360 / 4095)
    assert -1000 * 360 / 4095 <= pan.min < pan.mean < pan.max <= 1000 * 360 / 4095


@pytest.fixture()
def src(tmp_path: Path) -> Path:
    root = tmp_path / "src"
    generate_dataset(root, n_episodes=4, frames_per_episode=[30, 40, 25, 12], convention=A)
    return root


def test_inspect_counts_and_flags_nan(src: Path) -> None:
    path = src / "data/chunk-000/file-000.parquet"
    table = pq.read_table(path)
    vals = column(path, "action").astype(np.float32)
    vals[3, 2] = np.nan
    vals[4, 2] = np.inf
    col = pa.FixedSizeListArray.from_arrays(pa.array(vals.ravel()), 6)
    pq.write_table(table.set_column(1, table.schema.field(1), col), path)
    rep = inspect_dataset(src, features=["action"])
    elbow = next(j for j in rep.joints if j.joint == "elbow_flex")
    assert elbow.non_finite == 2 and elbow.flagged
    finite = vals[np.isfinite(vals[:, 2]), 2]
    assert elbow.min <= finite.min() and np.isfinite(elbow.max) and np.isfinite(elbow.mean)
    assert [j.joint for j in rep.flagged] == ["elbow_flex"]


def test_inspect_counts_a_null_row_as_not_finite_in_every_joint(src: Path) -> None:
    """A frame with no value (a null row) was dropped by Arrow's flatten from that column only: the values and
    the episode column no longer lined up and inspect died (exit 70). Now it is a non-finite frame of every joint."""
    path = src / "data/chunk-000/file-000.parquet"
    table = pq.read_table(path)
    rows = table.column("action").to_pylist()
    rows[4] = None
    i = table.schema.get_field_index("action")
    pq.write_table(table.set_column(i, "action", pa.array(rows, table.schema.field(i).type)), path)
    if not reads_null_list_rows():  # pyarrow 25: the file cannot be read back at all
        with pytest.raises(FileFormatError, match=r"cannot read Parquet \(Expected all lists to be of size=6"):
            inspect_dataset(src, features=["action"])
        return
    rep = inspect_dataset(src, features=["action"])
    assert rep.frames == 107
    assert {j.joint: j.non_finite for j in rep.joints} == dict.fromkeys(SO_ARM_JOINTS, 1)
    assert all(np.isfinite(j.mean) for j in rep.joints)


def test_inspect_refuses_an_episode_index_with_null_rows(src: Path) -> None:
    path = src / "data/chunk-000/file-000.parquet"
    table = pq.read_table(path)
    eps = table.column("episode_index").to_pylist()
    eps[7] = None
    i = table.schema.get_field_index("episode_index")
    pq.write_table(table.set_column(i, "episode_index", pa.array(eps, pa.int64())), path)
    with pytest.raises(FileFormatError, match=r"column 'episode_index' is int64 with null rows; expected an integer"):
        inspect_dataset(src)


def test_inspect_mixed_feature_with_calibration(lekiwi: Path) -> None:
    rep = inspect_dataset(lekiwi, calibration=lekiwi_conv(HOMING_A, RANGE_A))
    by_joint = {(j.feature, j.joint): j for j in rep.joints}
    assert by_joint[("action", "x.vel")].range_lo is None
    assert by_joint[("action", "arm_gripper")].range_lo == pytest.approx(0.0)
    assert rep.flagged == ()
