"""Make the dataset test helpers importable (``import dataset_testutil``) in importlib mode; shared fixtures."""

from __future__ import annotations

import sys
from pathlib import Path

import pytest

_HERE = str(Path(__file__).parent)
if _HERE not in sys.path:
    sys.path.insert(0, _HERE)

from dataset_testutil import ARM, HI, HOMING_A, LO, RANGE_A, add_velocities, lekiwi_conv  # noqa: E402

from robocal.dataset import generate_dataset  # noqa: E402


@pytest.fixture()
def lekiwi(tmp_path: Path) -> Path:
    root = tmp_path / "lekiwi"
    generate_dataset(
        root,
        n_episodes=3,
        frames_per_episode=[30, 40, 25],
        joint_names=ARM,
        convention=lekiwi_conv(HOMING_A, RANGE_A),
        actual_lo=LO,
        actual_hi=HI,
        robot_type="lekiwi",
    )
    add_velocities(root)
    return root
