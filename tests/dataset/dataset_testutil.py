"""Shared helpers for the dataset tests (no fixtures read outside the repository)."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq

from robocal.core.jointmap import RobotCalibration
from robocal.dataset import SO_ARM_JOINTS, JointMapConvention
from robocal.dataset.lerobot import LeRobotConvention, preset_modes
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


# --- LeKiwi: features that mix the arm's joint positions with base velocities; calibrations with wheels

ARM = tuple(f"arm_{j}" for j in SO_ARM_JOINTS)
WHEELS = ("base_left_wheel", "base_back_wheel", "base_right_wheel")
VELOCITIES = ("x.vel", "y.vel", "theta.vel")
FEATURES = ("observation.state", "action")


def lekiwi_cals(homing: list[int], ranges: list[tuple[int, int]]) -> dict[str, MotorCalibration]:
    """A LeKiwi calibration: the six arm motors and three base wheels (not in the features)."""
    out = {n: MotorCalibration(i + 1, 0, homing[i], ranges[i][0], ranges[i][1]) for i, n in enumerate(ARM)}
    for k, n in enumerate(WHEELS):
        out[n] = MotorCalibration(7 + k, 0, 0, 0, 4095)
    return out


def lekiwi_conv(homing: list[int], ranges: list[tuple[int, int]]) -> LeRobotConvention:
    cals = lekiwi_cals(homing, ranges)
    modes = preset_modes("lekiwi", list(cals))
    return LeRobotConvention.from_calibrations(cals, modes, "feetech")


def _velocity_bits(rng: np.random.Generator, n: int) -> np.ndarray:
    """float32 velocities with awkward bit patterns (−0.0, a subnormal, tiny and huge values)."""
    v = rng.normal(0.0, 0.3, size=(n, len(VELOCITIES))).astype(np.float32)
    specials = np.array([-0.0, 1e-40, 3.4e38, -1.17e-38], dtype=np.float32)
    v.flat[: specials.size] = specials
    return v


def add_velocities(root: Path, seed: int = 7) -> None:
    """Append ``x.vel``, ``y.vel``, ``theta.vel`` to both vector features (data, info, HF metadata, stats)."""
    rng = np.random.default_rng(seed)
    d = len(ARM) + len(VELOCITIES)
    for path in sorted(root.glob("data/chunk-*/file-*.parquet")):
        pf = pq.ParquetFile(path)
        hf = json.loads(pf.schema_arrow.metadata[b"huggingface"])
        for key in FEATURES:
            hf["info"]["features"][key]["length"] = d
        tables = []
        for g in range(pf.metadata.num_row_groups):
            t = pf.read_row_group(g)
            for key in FEATURES:
                arm = column_of(t, key)
                vals = np.concatenate([arm, _velocity_bits(rng, t.num_rows)], axis=1)
                i = t.schema.get_field_index(key)
                arr = pa.FixedSizeListArray.from_arrays(pa.array(vals.reshape(-1), pa.float32()), d)
                t = t.set_column(i, pa.field(key, arr.type), arr)
            tables.append(t)
        schema = tables[0].schema.with_metadata({b"huggingface": json.dumps(hf).encode()})
        with pq.ParquetWriter(path, schema) as writer:
            for t in tables:
                writer.write_table(t.cast(schema), row_group_size=t.num_rows)
    info_path = root / "meta/info.json"
    info = json.loads(info_path.read_text())
    info["robot_type"] = "lekiwi"
    for key in FEATURES:
        info["features"][key]["names"] += list(VELOCITIES)
        info["features"][key]["shape"] = [d]
    info_path.write_text(json.dumps(info, indent=4))


def column_of(table: pa.Table, key: str) -> np.ndarray:
    col = table.column(key).combine_chunks()
    return np.asarray(col.flatten().to_numpy(zero_copy_only=False)).reshape(-1, col.type.list_size)


def raw_values(root: Path, key: str) -> np.ndarray:
    """All frames of a feature in the stored dtype (float32), for bit comparisons."""
    files = sorted(root.glob("data/chunk-*/file-*.parquet"))
    return np.concatenate([column_of(pq.read_table(f), key) for f in files])

