"""Valid inputs for every reader, made by robocal's writers, its simulators and upstream examples."""

from __future__ import annotations

import functools
import json
import math
import tempfile
from pathlib import Path
from typing import Any

import numpy as np
from tests.bags import write_joint_states

from robocal.backends.sim.lite import LITE_JOINTS, lite_urdf_text
from robocal.core.jointmap import RobotCalibration
from robocal.core.lerobot import LegacyCalibration, MotorCalibration
from robocal.formats import write_calibration
from robocal.formats.lerobot import dumps_current, dumps_legacy

LITE_NAMES = [j.name for j in LITE_JOINTS]
SO_NAMES = ["shoulder_pan", "shoulder_lift", "elbow_flex", "wrist_flex", "wrist_roll", "gripper"]


def lite_calibration() -> RobotCalibration:
    """The Lite arm's joint map with varied offsets (one per joint)."""
    offsets = [0.1 * (i - 6) + 0.0123 for i in range(len(LITE_JOINTS))]
    return RobotCalibration(LITE_NAMES, [j.direction for j in LITE_JOINTS], offsets, 1.0)


@functools.cache
def calibration_seeds() -> dict[str, bytes]:
    """Format name → a valid file of that format (the Lite arm)."""
    from robocal.formats.urdf import parse_urdf

    urdf_text = lite_urdf_text()
    urdf = parse_urdf(urdf_text)
    cal = lite_calibration()
    out: dict[str, bytes] = {}
    with tempfile.TemporaryDirectory() as d:
        for fmt, name in [
            ("lite-json", "c.json"),
            ("lite-yaml", "c.yaml"),
            ("berkeley-offsets", "b.json"),
            ("robocal", "r.yaml"),
        ]:
            p = Path(d) / name
            write_calibration(p, cal, fmt, urdf=urdf, joint_order=LITE_NAMES)
            out[fmt] = p.read_bytes()
        p = Path(d) / "t.urdf"
        p.write_text(urdf_text)
        write_calibration(p, cal, "ros2-transmission", urdf=urdf)
        out["ros2-transmission"] = p.read_bytes()
    out["lerobot-legacy"] = legacy_seed().encode()
    # Humanoid-Control's calibration.yaml style, with comments (what lite-yaml updates in place)
    out["lite-yaml-commented"] = (
        "# Lite arm calibration\n"
        + "".join(
            f"{n}:  # joint {i}\n  id: {j.can_id}\n  direction: {j.direction}\n  homing_offset: {0.25 * i - 1.5}\n"
            for i, (n, j) in enumerate(zip(LITE_NAMES, LITE_JOINTS, strict=True))
        )
    ).encode()
    return out


def current_cals() -> dict[str, MotorCalibration]:
    """An SO-101 follower's current LeRobot calibration."""
    homing = [100, -40, 60, 0, -120, 0]
    ranges = [(900, 2950), (1000, 3000), (950, 3100), (1000, 3000), (0, 4095), (1000, 3000)]
    return {
        n: MotorCalibration(i + 1, 0, homing[i], ranges[i][0], ranges[i][1]) for i, n in enumerate(SO_NAMES)
    }


def current_seed() -> str:
    """LeRobot current calibration JSON (what ``lerobot-calibrate`` writes)."""
    return dumps_current(current_cals())


def legacy_seed() -> str:
    """LeRobot legacy array JSON (2024 → 2025-06), DEGREE joints and a LINEAR gripper."""
    cal = LegacyCalibration(
        SO_NAMES,
        np.array([-2048, 1024, -1024, 2048, -2048, 0]),
        np.array([0, 1, 0, 1, 0, 0]),
        np.array([0, 0, 0, 0, 0, 2000]),
        np.array([0, 0, 0, 0, 0, 3000]),
        ["DEGREE"] * 5 + ["LINEAR"],
    )
    return dumps_legacy(cal)


DH_YAML = (
    "dh_theta: [0, 0, 0, 0, 0, 0]\n"
    "dh_a: [0, -0.6127, -0.57155, 0, 0, 0]\n"
    "dh_d: [0.1807, 0, 0, 0.17415, 0.11985, 0.11655]\n"
    "dh_alpha: [1.570796327, 0, 0, 1.570796327, -1.570796327, 0]\n"
)
DELTAS_YAML = (
    "delta_theta: [0.0001, 0, 0, 0, 0, 0]\n"
    "delta_a: [0, 0.0002, 0, 0, 0, 0]\n"
    "delta_d: [0, 1.5, -1.5, 0, 0, 0]\n"
    "delta_alpha: [0, 0, 0.0003, 0, 0, 0]\n"
)
CALIBRATION_CONF = (
    "# robot calibration file\n"
    "[mounting]\n"
    "calibration_status = 2\n"
    "delta_theta = [ 1.1e-05, -0.3208, 0.4578,\n"
    "               -0.1370, 2.5e-05, 0.0 ]\n"
    "delta_a = [0, 0.0002, 0.0012, 0, 0, 0]\n"
    "; a comment line\n"
    "delta_d = [0, 1.5, -1.5, 0, 0, 0]  # trailing comment\n"
    "delta_alpha = [0, 0, 0.0003, 0, 0, 0]\n"
    "joint_checksum = [ 0xb3241580, 0x1, -1, -1, -1, -1 ]\n"
)


def dh_tree() -> dict[str, Any]:
    """The DH YAML seed as plain data."""
    return {
        "dh_theta": [0, 0, 0, 0, 0, 0],
        "dh_a": [0, -0.6127, -0.57155, 0, 0, 0],
        "dh_d": [0.1807, 0, 0, 0.17415, 0.11985, 0.11655],
        "dh_alpha": [1.570796327, 0, 0, 1.570796327, -1.570796327, 0],
    }


def csv_seed(rows: int = 30) -> str:
    """A replay CSV of the Lite arm: ``t,<joint>...`` sweeping every joint."""
    lines = ["t," + ",".join(LITE_NAMES)]
    for i in range(rows):
        values = [0.01 * i] + [0.5 * math.sin(0.3 * i + k) for k in range(len(LITE_NAMES))]
        lines.append(",".join(repr(float(v)) for v in values))
    return "\n".join(lines) + "\n"


def write_bag(path: Path, plugin: str, rows: int = 10, topic: str = "/lite/joint_states") -> None:
    """A rosbag2 (``sqlite3`` or ``mcap``) of ``rows`` JointState messages of the Lite arm, 10 ms apart."""
    positions = [[0.5 * np.sin(0.3 * i + k) for k in range(len(LITE_NAMES))] for i in range(rows)]
    write_joint_states(path, LITE_NAMES, [i * 0.01 for i in range(rows)], positions, plugin=plugin, topic=topic)


@functools.cache
def bag_seed(plugin: str) -> dict[str, bytes]:
    """Relative path → bytes of every file of a small valid bag folder."""
    with tempfile.TemporaryDirectory() as d:
        bag = Path(d) / "bag"
        write_bag(bag, plugin)
        return {p.relative_to(bag).as_posix(): p.read_bytes() for p in sorted(bag.rglob("*")) if p.is_file()}


DATASET_RECALIBRATE = (
    "dataset", "recalibrate", "ds", "out", "--old", "cal.json", "--new", "new.json", "--robot", "so101_follower"
)
"""The recalibrate command over :func:`dataset_seed` written as ``ds`` (with ``cal.json`` and ``new.json``)."""


@functools.cache
def dataset_seed() -> dict[str, bytes]:
    """Relative path → bytes of every file of a small synthetic LeRobot v3 dataset."""
    from robocal.dataset import generate_dataset

    with tempfile.TemporaryDirectory() as d:
        root = Path(d) / "ds"
        generate_dataset(root, n_episodes=2, frames_per_episode=12, episodes_per_file=1, seed=3)
        return {
            p.relative_to(root).as_posix(): p.read_bytes() for p in sorted(root.rglob("*")) if p.is_file()
        }


def write_tree(root: Path, files: dict[str, bytes]) -> None:
    """Write ``files`` (relative path → bytes) under ``root``."""
    for rel, data in files.items():
        p = root / rel
        p.parent.mkdir(parents=True, exist_ok=True)
        p.write_bytes(data)


def json_text(data: bytes) -> str:
    """Decode a seed known to be UTF-8 JSON (kept valid: checked here)."""
    text = data.decode()
    json.loads(text)
    return text
