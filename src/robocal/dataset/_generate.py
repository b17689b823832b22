"""Synthetic LeRobot v3 datasets for tests and benchmarks.

The generator draws smooth joint trajectories as integer *actual* encoder ticks (what a servo reports with no
homing offset), turns them into stored values with a :class:`~robocal.dataset.ValueConvention` (or uses
the ticks as values when none is given) and writes a dataset root laid out like LeRobot's:
``meta/info.json``, ``data/chunk-000/file-NNN.parquet`` with one row group per episode and HF schema
metadata, ``meta/stats.json``,
``meta/episodes/chunk-000/file-000.parquet`` with per-episode statistics, ``meta/tasks.parquet``, and a dummy
video file that must be carried over untouched.
"""

from __future__ import annotations

import json
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq
from numpy.typing import NDArray

from ..errors import UsageError
from ._convention import ValueConvention
from ._stats import StatAccumulator, merge_all

__all__ = ["SO_ARM_JOINTS", "GeneratedDataset", "generate_dataset"]

SO_ARM_JOINTS: tuple[str, ...] = (
    "shoulder_pan",
    "shoulder_lift",
    "elbow_flex",
    "wrist_flex",
    "wrist_roll",
    "gripper",
)
"""Motor names of LeRobot's SO-100/SO-101 arms (also Koch's), in bus order."""

_VECTOR_FEATURES = ("observation.state", "action")
_STAT_NAMES = ("min", "max", "mean", "std", "count", "q01", "q10", "q50", "q90", "q99")
VIDEO_KEY = "observation.images.front"


@dataclass(frozen=True)
class GeneratedDataset:
    """A generated dataset.

    Attributes:
        root: Dataset root.
        joint_names: Joint names of both vector features.
        n_episodes: Number of episodes.
        n_frames: Total number of frames.
        data_files: Data files relative to ``root``.
    """

    root: Path
    joint_names: tuple[str, ...]
    n_episodes: int
    n_frames: int
    data_files: tuple[str, ...]


def _hf_metadata(d: int) -> bytes:
    vec = {"feature": {"dtype": "float32", "_type": "Value"}, "length": d, "_type": "Sequence"}
    feats: dict[str, Any] = {
        "observation.state": vec,
        "action": vec,
        "timestamp": {"dtype": "float32", "_type": "Value"},
        "frame_index": {"dtype": "int64", "_type": "Value"},
        "episode_index": {"dtype": "int64", "_type": "Value"},
        "index": {"dtype": "int64", "_type": "Value"},
        "task_index": {"dtype": "int64", "_type": "Value"},
    }
    return json.dumps({"info": {"features": feats}}).encode()


def data_schema(d: int) -> pa.Schema:
    """Arrow schema of a generated data file with ``d`` joints (HF metadata included)."""
    vec = pa.list_(pa.float32(), d)
    return pa.schema(
        [
            ("observation.state", vec),
            ("action", vec),
            ("timestamp", pa.float32()),
            ("frame_index", pa.int64()),
            ("episode_index", pa.int64()),
            ("index", pa.int64()),
            ("task_index", pa.int64()),
        ],
        metadata={b"huggingface": _hf_metadata(d)},
    )



def episode_table(
    schema: pa.Schema, state: NDArray[np.float32], action: NDArray[np.float32], ts: NDArray[np.float32],
    episode: int, first_index: int,
) -> pa.Table:  # fmt: skip
    """One episode's rows of a data file: ``(n, D)`` state and action, ``(n,)`` timestamps (s), task 0.

    ``first_index`` is the dataset-wide ``index`` of its first frame.
    """
    n, d = state.shape
    return pa.table(
        {
            "observation.state": pa.FixedSizeListArray.from_arrays(pa.array(state.ravel()), d),
            "action": pa.FixedSizeListArray.from_arrays(pa.array(action.ravel()), d),
            "timestamp": pa.array(ts),
            "frame_index": pa.array(np.arange(n, dtype=np.int64)),
            "episode_index": pa.array(np.full(n, episode, dtype=np.int64)),
            "index": pa.array(np.arange(first_index, first_index + n, dtype=np.int64)),
            "task_index": pa.array(np.zeros(n, dtype=np.int64)),
        }
    ).cast(schema)


def episode_row(
    episode: int, task: str, length: int, file_index: int, first_index: int, video_key: str | None = None
) -> dict[str, Any]:
    """An episode's row of ``meta/episodes`` (chunk 0; a video's chunk and file 0); statistics: :func:`add_stats`."""
    row: dict[str, Any] = {
        "episode_index": episode,
        "tasks": [task],
        "length": length,
        "data/chunk_index": 0,
        "data/file_index": file_index,
        "dataset_from_index": first_index,
        "dataset_to_index": first_index + length,
    }
    if video_key is not None:
        row[f"videos/{video_key}/chunk_index"] = 0
        row[f"videos/{video_key}/file_index"] = 0
    row["meta/episodes/chunk_index"] = 0
    row["meta/episodes/file_index"] = 0
    return row


def add_stats(row: dict[str, Any], acc: Mapping[str, StatAccumulator]) -> None:
    """Add one episode's ``stats/<feature>/<stat>`` columns to its row, feature by feature."""
    for key, a in acc.items():
        for stat in _STAT_NAMES:
            row[f"stats/{key}/{stat}"] = a.get(stat)


def merged_stats(accs: Sequence[Mapping[str, StatAccumulator]], keys: Sequence[str]) -> dict[str, Any]:
    """``meta/stats.json``'s document: the episodes' statistics merged, per feature of ``keys``."""
    stats: dict[str, Any] = {}
    for key in keys:
        total = merge_all(a[key] for a in accs)
        assert total is not None
        stats[key] = {stat: total.get(stat) for stat in _STAT_NAMES}
    return stats


def info_document(
    names: Sequence[str], vector_keys: Sequence[str], robot_type: str, episodes: int, frames: int, fps: int,
    video_key: str | None = None,
) -> dict[str, Any]:  # fmt: skip
    """``meta/info.json``'s document: the vector features (``"<motor>.pos"``) in ``vector_keys`` order, a video."""
    d = len(names)
    features: dict[str, Any] = {
        key: {"dtype": "float32", "shape": [d], "names": [f"{n}.pos" for n in names]} for key in vector_keys
    }
    if video_key is not None:
        features[video_key] = {
            "dtype": "video",
            "shape": [48, 64, 3],
            "names": ["height", "width", "channels"],
            "info": {"video.fps": fps, "video.codec": "av1"},
        }
    for key, dt in (
        ("timestamp", "float32"),
        ("frame_index", "int64"),
        ("episode_index", "int64"),
        ("index", "int64"),
        ("task_index", "int64"),
    ):
        features[key] = {"dtype": dt, "shape": [1], "names": None}
    return {
        "codebase_version": "v3.0",
        "robot_type": robot_type,
        "total_episodes": episodes,
        "total_frames": frames,
        "total_tasks": 1,
        "chunks_size": 1000,
        "data_files_size_in_mb": 100,
        "video_files_size_in_mb": 500,
        "fps": fps,
        "splits": {"train": f"0:{episodes}"},
        "data_path": "data/chunk-{chunk_index:03d}/file-{file_index:03d}.parquet",
        "video_path": None
        if video_key is None
        else "videos/{video_key}/chunk-{chunk_index:03d}/file-{file_index:03d}.mp4",
        "features": features,
    }


def write_tasks(root: Path, task: str) -> None:
    """``meta/tasks.parquet`` with the one task."""
    pq.write_table(
        pa.table({"task_index": pa.array([0], pa.int64()), "task": pa.array([task])}), root / "meta" / "tasks.parquet"
    )

def _trajectory(
    rng: np.random.Generator, n: int, lo: NDArray[np.float64], hi: NDArray[np.float64]
) -> NDArray[np.float64]:
    """Integer ticks ``(n, D)``: a sum of two sinusoids per joint inside ``[lo, hi]``."""
    d = lo.shape[0]
    t = np.arange(n, dtype=np.float64)[:, None]
    f1 = rng.uniform(0.002, 0.02, d)
    f2 = rng.uniform(0.02, 0.08, d)
    p1 = rng.uniform(0, 2 * np.pi, d)
    p2 = rng.uniform(0, 2 * np.pi, d)
    s = 0.7 * np.sin(2 * np.pi * f1 * t + p1) + 0.3 * np.sin(2 * np.pi * f2 * t + p2)  # in [-1, 1]
    mid = 0.5 * (lo + hi)
    half = 0.5 * (hi - lo)
    out: NDArray[np.float64] = np.round(mid + half * s)
    return out


def generate_dataset(
    root: str | Path,
    *,
    n_episodes: int = 4,
    frames_per_episode: int | Sequence[int] = 50,
    episodes_per_file: int = 2,
    joint_names: Sequence[str] = SO_ARM_JOINTS,
    convention: ValueConvention | None = None,
    actual_lo: Sequence[float] | None = None,
    actual_hi: Sequence[float] | None = None,
    robot_type: str = "so101_follower",
    fps: int = 30,
    seed: int = 0,
    with_stats: bool = True,
) -> GeneratedDataset:
    """Write a synthetic LeRobot v3 dataset.

    Args:
        root: Folder to create (must not exist).
        n_episodes: Number of episodes.
        frames_per_episode: Frames per episode, one number or one per episode.
        episodes_per_file: Episodes per data file (each episode is one row group).
        joint_names: Motor names; feature entries are ``"<motor>.pos"``.
        convention: Maps actual ticks to stored values; ``None`` stores the ticks themselves.
        actual_lo: Lowest actual tick per joint (default 1100).
        actual_hi: Highest actual tick per joint (default 2900).
        robot_type: ``robot_type`` written to ``info.json``.
        fps: Frames per second.
        seed: Random seed.
        with_stats: Write ``meta/stats.json`` and per-episode statistics.

    Returns:
        What was written.
    """
    r = Path(root)
    if r.exists():
        raise UsageError(f"generate_dataset: {r} already exists")
    names = tuple(joint_names)
    d = len(names)
    if isinstance(frames_per_episode, int):
        lengths = [frames_per_episode] * n_episodes
    else:
        lengths = [int(x) for x in frames_per_episode]
    if len(lengths) != n_episodes or min(lengths, default=1) < 1 or episodes_per_file < 1:
        raise UsageError("generate_dataset: need one positive length per episode and episodes_per_file ≥ 1")
    conv = convention.select(names) if convention is not None else None
    lo = np.full(d, 1100.0) if actual_lo is None else np.asarray(actual_lo, dtype=np.float64)
    hi = np.full(d, 2900.0) if actual_hi is None else np.asarray(actual_hi, dtype=np.float64)
    rng = np.random.default_rng(seed)
    schema = data_schema(d)
    (r / "meta").mkdir(parents=True)
    data_dir = r / "data" / "chunk-000"
    data_dir.mkdir(parents=True)

    stats_keys = ("observation.state", "action", "timestamp")
    ep_rows: list[dict[str, Any]] = []
    ep_acc: list[dict[str, StatAccumulator]] = []
    data_files: list[str] = []
    index = 0
    writer: pq.ParquetWriter | None = None
    file_index = -1
    for ep, n in enumerate(lengths):
        if ep % episodes_per_file == 0:
            if writer is not None:
                writer.close()
            file_index += 1
            rel = f"data/chunk-000/file-{file_index:03d}.parquet"
            data_files.append(rel)
            writer = pq.ParquetWriter(r / rel, schema=schema, compression="snappy")
        assert writer is not None
        actual_state = _trajectory(rng, n, lo, hi)
        actual_action = np.clip(actual_state + rng.integers(-3, 4, size=actual_state.shape), lo, hi)
        if conv is not None:
            state, _ = conv.from_actual(actual_state)
            action, _ = conv.from_actual(actual_action)
        else:
            state, action = actual_state, actual_action
        state32 = state.astype(np.float32)
        action32 = action.astype(np.float32)
        ts = (np.arange(n) / fps).astype(np.float32)
        writer.write_table(episode_table(schema, state32, action32, ts, ep, index), row_group_size=n)
        acc = {
            "observation.state": StatAccumulator.of(state32.astype(np.float64)),
            "action": StatAccumulator.of(action32.astype(np.float64)),
            "timestamp": StatAccumulator.of(ts.astype(np.float64)[:, None]),
        }
        ep_acc.append(acc)
        row = episode_row(ep, "pick the cube", n, file_index, index, VIDEO_KEY)
        if with_stats:
            add_stats(row, acc)
        ep_rows.append(row)
        index += n
    if writer is not None:
        writer.close()

    info = info_document(names, _VECTOR_FEATURES, robot_type, n_episodes, index, fps, VIDEO_KEY)
    (r / "meta" / "info.json").write_text(json.dumps(info, indent=4))
    write_tasks(r, "pick the cube")
    ep_dir = r / "meta" / "episodes" / "chunk-000"
    ep_dir.mkdir(parents=True)
    pq.write_table(pa.Table.from_pylist(ep_rows), ep_dir / "file-000.parquet")
    if with_stats:
        (r / "meta" / "stats.json").write_text(json.dumps(merged_stats(ep_acc, stats_keys), indent=4))
    video = r / "videos" / VIDEO_KEY / "chunk-000" / "file-000.mp4"
    video.parent.mkdir(parents=True)
    video.write_bytes(bytes(rng.integers(0, 256, size=4096, dtype=np.uint8)))
    (r / "README.md").write_text("Synthetic LeRobot v3 dataset (robocal.dataset.generate_dataset).\n")
    return GeneratedDataset(
        root=r, joint_names=names, n_episodes=n_episodes, n_frames=index, data_files=tuple(data_files)
    )
