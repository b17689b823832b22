"""The joint frames of a LeRobot v3 teleoperation dataset, read and checked for the health check.

``action`` (the leader) and ``observation.state`` (the follower) per frame with its episode, in episode order;
every row must carry both values, an integer episode, and (where the files have a ``frame_index``) each frame once.
"""

from __future__ import annotations

from collections import Counter
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq

from ..core.arrays import FloatArray, IntArray
from ..errors import FileFormatError, JointMismatchError, UsageError
from ._layout import read_layout

__all__ = ["TeleopFrames", "episode_numbers", "read_teleop_frames"]


@dataclass(frozen=True, eq=False)
class TeleopFrames:
    """A dataset's joint frames.

    Attributes:
        root: Dataset root.
        joints: Joint names (column order of both features).
        action: ``(N, J)`` leader values.
        state: ``(N, J)`` follower values.
        episode: ``(N,)`` episode index per frame.
    """

    root: Path
    joints: tuple[str, ...]
    action: FloatArray
    state: FloatArray
    episode: IntArray


def _vector(table: pa.Table, key: str, d: int, rel: str) -> FloatArray:
    arr = table.column(key).combine_chunks()
    if not pa.types.is_fixed_size_list(arr.type) or arr.type.list_size != d:
        raise FileFormatError(
            f"data file {rel}: column {key!r} is {arr.type}; expected fixed_size_list<float>[{d}]"
        )
    if arr.null_count:
        raise FileFormatError(
            f"data file {rel}: column {key!r} has null rows (frames with no value); the check needs every frame"
        )
    with np.errstate(invalid="ignore", over="ignore"):
        v = np.asarray(arr.flatten().to_numpy(zero_copy_only=False), dtype=np.float64)
    return v.reshape(-1, d)


def episode_numbers(table: pa.Table, rel: str, what: str = "data file") -> IntArray:
    """The ``episode_index`` column of a data file's rows: an integer in every row.

    ``what`` names the file in the message (``"episodes file"`` for ``meta/episodes``).

    Raises:
        FileFormatError: Another type, or null rows (numpy would cast them with a warning, or truncate a float).
    """
    ep = table.column("episode_index")
    if not pa.types.is_integer(ep.type) or ep.null_count:
        nulls = " with null rows" if ep.null_count else ""
        raise FileFormatError(
            f"{what} {rel}: column 'episode_index' is {ep.type}{nulls}; expected an integer episode number in "
            "every row"
        )
    out: IntArray = np.asarray(ep.to_numpy(), dtype=np.int64)
    return out


def read_teleop_frames(root: str | Path) -> TeleopFrames:
    """Read ``action`` and ``observation.state`` of every frame, in episode order.

    Raises:
        FileFormatError: A malformed dataset, a missing column, NaN or infinite values.
        JointMismatchError: The two features name different joints.
        UsageError: Fewer than 2 frames.
    """
    layout = read_layout(root)
    for key in ("action", "observation.state"):
        if key not in layout.features:
            raise FileFormatError(
                f"{layout.root / 'meta/info.json'}: no {key!r} feature; a teleoperation dataset has both "
                "action (the leader) and observation.state (the follower)"
            )
    fa, fs = layout.vector_feature("action"), layout.vector_feature("observation.state")
    if fa.joint_names != fs.joint_names:
        raise JointMismatchError(
            f"{layout.root / 'meta/info.json'}: action names {', '.join(fa.joint_names)} but observation.state "
            f"names {', '.join(fs.joint_names)}; the check pairs them joint by joint"
        )
    dup = sorted(n for n, count in Counter(fa.joint_names).items() if count > 1)
    if dup:
        raise JointMismatchError(
            f"{layout.root / 'meta/info.json'}: action and observation.state name {', '.join(dup)} more than "
            "once; the check reports each joint by name"
        )
    actions, states, episodes, frames = [], [], [], []
    for rel in layout.data_files:
        try:
            pf = pq.ParquetFile(layout.root / rel)
            names = pf.schema_arrow.names
            missing = [c for c in ("action", "observation.state", "episode_index") if c not in names]
            if missing:
                raise FileFormatError(f"data file {rel}: missing column(s) {', '.join(missing)}")
            extra = ["frame_index"] if "frame_index" in names else []
            for g in range(pf.metadata.num_row_groups):
                t = pf.read_row_group(g, columns=["action", "observation.state", "episode_index", *extra])
                actions.append(_vector(t, "action", fa.size, rel))
                states.append(_vector(t, "observation.state", fs.size, rel))
                episodes.append(episode_numbers(t, rel))
                index = np.full(t.num_rows, -1, dtype=np.int64)  # -1: no frame_index to compare
                if extra:
                    fi = t.column("frame_index")
                    if pa.types.is_integer(fi.type) and not fi.null_count:
                        index = np.asarray(fi.to_numpy(), dtype=np.int64)
                frames.append(index)
        except (pa.ArrowException, OSError) as exc:
            raise FileFormatError(f"data file {rel}: cannot read Parquet ({exc})") from None
    if not actions or sum(len(a) for a in actions) < 2:
        raise UsageError(f"dataset {layout.root}: fewer than 2 frames; nothing to check")
    action, state, episode = np.concatenate(actions), np.concatenate(states), np.concatenate(episodes)
    for key, v in (("action", action), ("observation.state", state)):
        bad = ~np.isfinite(v)
        if bad.any():
            row, col = (int(x[0]) for x in np.nonzero(bad))
            raise FileFormatError(
                f"dataset {layout.root}: {int(bad.sum())} NaN or infinite value(s) in {key} "
                f"(first: joint {fa.joint_names[col]}, frame {row}); the check needs every frame"
            )
    order = np.argsort(episode, kind="stable")
    _no_repeated_frames(layout.root, episode[order], np.concatenate(frames)[order])
    return TeleopFrames(layout.root, fa.joint_names, action[order], state[order], episode[order])


def _no_repeated_frames(root: Path, episode: IntArray, frame: IntArray) -> None:
    """A frame (episode, frame_index) recorded twice: a data file copied, or two recordings merged.

    Its rows would be read as one session going back in time (steps on every joint). Frames without a
    ``frame_index`` (-1) are not compared.

    Raises:
        FileFormatError: A repeated frame, the first one named.
    """
    known = frame >= 0
    if not known.any():
        return
    pairs = np.stack([episode[known], frame[known]], axis=1)
    unique, counts = np.unique(pairs, axis=0, return_counts=True)
    if counts.max() > 1:
        ep, fr = (int(x) for x in unique[int(np.argmax(counts > 1))])
        raise FileFormatError(
            f"dataset {root}: frame {fr} of episode {ep} is recorded {int(counts.max())} times "
            f"({int((counts > 1).sum())} frame(s) repeated: a data file copied, or two recordings merged); "
            "the check needs each frame once"
        )
