"""Shared helpers for the dataset tests (no fixtures read outside the repository)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pyarrow.parquet as pq

from robocal.core.jointmap import RobotCalibration
from robocal.dataset import SO_ARM_JOINTS, JointMapConvention
from robocal.lerobot import MotorCalibration

TICK_RAD = 2 * np.pi / 4096


def joint_map(direction: list[int], offset: list[float]) -> JointMapConvention:
    return JointMapConvention(RobotCalibration(SO_ARM_JOINTS, direction, offset, TICK_RAD), turn_raw=4096)


A = joint_map([1, -1, 1, 1, -1, 1], [2047, 2000, 2100, 1900, 2047, 2047])
B = joint_map([1, 1, 1, -1, -1, 1], [2000, 2010, 2150, 1950, 2000, 2047])


def column(path: Path, key: str) -> np.ndarray:
    table = pq.read_table(path)
    col = table.column(key).combine_chunks()
    return np.asarray(col.flatten().to_numpy(), dtype=np.float64).reshape(-1, col.type.list_size)


def all_values(root: Path, key: str) -> np.ndarray:
    files = sorted(root.glob("data/chunk-*/file-*.parquet"))
    return np.concatenate([column(f, key) for f in files])


def tree(root: Path) -> list[str]:
    return sorted(p.relative_to(root).as_posix() for p in root.rglob("*"))


# two LeRobot current-scheme calibrations of an SO-101 arm and the actual-tick travel the datasets use
HOMING_A = [100, -40, 60, 0, -120, 0]
HOMING_B = [-150, 30, -90, 200, 50, 500]
RANGE_A = [(900, 2950), (1000, 3000), (950, 3100), (1000, 3000), (0, 4095), (1000, 3000)]
RANGE_B = [(1200, 3100), (1050, 2900), (1000, 3050), (800, 2750), (0, 4095), (0, 2000)]
LO = [1100, 1100, 1100, 1100, 200, 1100]
HI = [2800, 2800, 2800, 2700, 3900, 2400]


def cals(
    homing: list[int], ranges: list[tuple[int, int]], drive: list[int] | None = None
) -> dict[str, MotorCalibration]:
    drive = drive or [0] * 6
    return {
        n: MotorCalibration(i + 1, drive[i], homing[i], ranges[i][0], ranges[i][1])
        for i, n in enumerate(SO_ARM_JOINTS)
    }
