"""Shared helpers for the dataset tests (no fixtures read outside the repository)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pyarrow.parquet as pq

from robocal.core.jointmap import RobotCalibration
from robocal.dataset import SO_ARM_JOINTS, JointMapConvention

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
