"""The two LeRobot v3 dataset writers, ``generate_dataset`` (tests, benchmarks) and ``write_teleop_dataset`` (the
health check's simulated sessions), share one writer of episode tables, episode rows, statistics and info; each
keeps the layout it wrote before they shared it (pinned here, column by column and byte by byte where it matters)."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pyarrow.parquet as pq
import pytest

from robocal.backends.sim.teleop import TeleopFaults
from robocal.dataset import generate_dataset
from robocal.dataset.teleop_sim import generate_teleop_datasets

STATS = ["min", "max", "mean", "std", "count", "q01", "q10", "q50", "q90", "q99"]
ROW_HEAD = ["episode_index", "tasks", "length", "data/chunk_index", "data/file_index", "dataset_from_index",
            "dataset_to_index"]  # fmt: skip
ROW_TAIL = ["meta/episodes/chunk_index", "meta/episodes/file_index"]
SCALARS = ["timestamp", "frame_index", "episode_index", "index", "task_index"]
VIDEO = "observation.images.front"


def _stat_columns(*features: str) -> list[str]:
    return [f"stats/{f}/{s}" for f in features for s in STATS]


@pytest.fixture(scope="module")
def teleop_root(tmp_path_factory: pytest.TempPathFactory) -> Path:
    folder = tmp_path_factory.mktemp("teleop")
    (root,) = generate_teleop_datasets(folder, "so101", [1], [TeleopFaults()], episodes=2, episode_s=2.0)
    return root


def test_teleop_dataset_layout(teleop_root: Path) -> None:
    r = teleop_root
    episodes = pq.read_table(r / "meta/episodes/chunk-000/file-000.parquet")
    assert episodes.column_names == ROW_HEAD + ROW_TAIL + _stat_columns("observation.state", "action")
    rows = episodes.select(ROW_HEAD).to_pylist()
    assert rows == [
        {"episode_index": 0, "tasks": ["teleoperate"], "length": 60, "data/chunk_index": 0, "data/file_index": 0,
         "dataset_from_index": 0, "dataset_to_index": 60},
        {"episode_index": 1, "tasks": ["teleoperate"], "length": 60, "data/chunk_index": 0, "data/file_index": 0,
         "dataset_from_index": 60, "dataset_to_index": 120},
    ]  # fmt: skip
    info_text = (r / "meta/info.json").read_text()
    assert info_text.startswith('{\n  "codebase_version": "v3.0",\n  "robot_type": "so101_follower",')
    info = json.loads(info_text)
    assert list(info["features"]) == ["action", "observation.state", *SCALARS]
    assert (info["total_episodes"], info["total_frames"], info["fps"], info["video_path"]) == (2, 120, 30, None)
    assert info["features"]["action"]["names"][0] == "shoulder_pan.pos"
    stats = json.loads((r / "meta/stats.json").read_text())
    assert {k: list(v) for k, v in stats.items()} == {"observation.state": STATS, "action": STATS}
    assert stats["action"]["count"] == [120]
    assert pq.read_table(r / "meta/tasks.parquet").to_pylist() == [{"task_index": 0, "task": "teleoperate"}]
    data = pq.ParquetFile(r / "data/chunk-000/file-000.parquet")
    assert data.metadata.num_row_groups == 2  # one per episode
    table = data.read()
    assert table.column("index").to_pylist() == list(range(120))
    assert table.column("episode_index").to_pylist() == [0] * 60 + [1] * 60
    np.testing.assert_array_equal(table.column("timestamp").to_numpy()[:3], np.float32([0, 1 / 30, 2 / 30]))
    assert r.with_name(r.name + ".truth.json").is_file()


def test_generated_dataset_layout(tmp_path: Path) -> None:
    r = tmp_path / "gen"
    generate_dataset(r, n_episodes=3, frames_per_episode=[5, 7, 4], episodes_per_file=2)
    episodes = pq.read_table(r / "meta/episodes/chunk-000/file-000.parquet")
    video_cells = [f"videos/{VIDEO}/chunk_index", f"videos/{VIDEO}/file_index"]
    stats_columns = _stat_columns("observation.state", "action", "timestamp")
    assert episodes.column_names == ROW_HEAD + video_cells + ROW_TAIL + stats_columns
    assert episodes.select(["data/file_index", "dataset_from_index", "dataset_to_index"]).to_pylist() == [
        {"data/file_index": 0, "dataset_from_index": 0, "dataset_to_index": 5},
        {"data/file_index": 0, "dataset_from_index": 5, "dataset_to_index": 12},
        {"data/file_index": 1, "dataset_from_index": 12, "dataset_to_index": 16},
    ]
    info_text = (r / "meta/info.json").read_text()
    assert info_text.startswith('{\n    "codebase_version": "v3.0",')
    info = json.loads(info_text)
    assert list(info["features"]) == ["observation.state", "action", VIDEO, *SCALARS]
    assert info["video_path"] == "videos/{video_key}/chunk-{chunk_index:03d}/file-{file_index:03d}.mp4"
    assert (info["total_episodes"], info["total_frames"]) == (3, 16)
    stats = json.loads((r / "meta/stats.json").read_text())
    assert list(stats) == ["observation.state", "action", "timestamp"]
    assert pq.read_table(r / "meta/tasks.parquet").to_pylist() == [{"task_index": 0, "task": "pick the cube"}]
    assert [pq.ParquetFile(r / f"data/chunk-000/file-00{i}.parquet").metadata.num_row_groups for i in (0, 1)] == [2, 1]


def test_generated_dataset_without_stats(tmp_path: Path) -> None:
    r = tmp_path / "gen"
    generate_dataset(r, n_episodes=2, frames_per_episode=3, with_stats=False)
    assert not (r / "meta/stats.json").exists()
    columns = pq.read_schema(r / "meta/episodes/chunk-000/file-000.parquet").names
    assert not [c for c in columns if c.startswith("stats/")]
