"""Recorded joint positions: CSV files and rosbag2 recordings (sqlite3 or mcap) of JointState messages.

CSV: a header ``t,<joint>,<joint>,…`` then one row per sample (``t`` in s, positions in rad). Columns of
joints robocal does not know are ignored; a known joint without a column has no samples (NaN).

rosbag2: a bag folder (with ``metadata.yaml``) or a single ``.db3`` / ``.mcap`` file, read with the
``rosbags`` library; ``sensor_msgs/msg/JointState`` messages on ``topic`` are matched to joints by name.
The time stamp is the message header's.

Missing positions, the same for both: a NaN position (legal in a ROS ``JointState``; written as ``nan`` in a
CSV) means "no reading of this joint in this sample" and is kept as NaN, so the sweep skips that joint's sample
and counts it; a joint absent from a message or without a CSV column is NaN too. An infinite position is never
a reading and is refused (``FileFormatError`` naming the line or time stamp), in both formats.
"""

from __future__ import annotations

import csv
import io
import math
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt

from ..errors import FileFormatError, JointMismatchError
from ..fileio import read_text
from . import require

__all__ = ["read_csv_recording", "read_recording", "read_rosbag_recording"]

FloatArray = npt.NDArray[np.float64]
MAX_ROWS = 50_000_000
MAX_ABS_POSITION_RAD = 1.0e4
"""Largest joint position accepted from a recording, rad (beyond it the unwrapping loses all precision)."""


def _check_matched(found: Sequence[str], joint_names: Sequence[str], where: str) -> None:
    if not any(n in found for n in joint_names):
        raise JointMismatchError(
            f"{where}: 0/{len(joint_names)} joints matched; it has {', '.join(found) or 'no joints'}, "
            f"expected some of {', '.join(joint_names)}"
        )


def read_csv_recording(path: Path, joint_names: Sequence[str]) -> tuple[FloatArray, FloatArray]:
    """Read a CSV recording.

    Args:
        path: The file.
        joint_names: Joints in the order wanted.

    Returns:
        ``(t (T,), positions (T, N))``; missing joints are NaN columns.

    Raises:
        FileFormatError: No ``t`` column, a non-numeric cell, a non-finite time, an infinite position, a short
            row, no rows. A NaN position (``nan``) is kept as NaN: no reading of that joint in that row.
        JointMismatchError: None of the joints has a column.
    """
    text = read_text(path, "recording")
    rows = list(csv.reader(io.StringIO(text)))
    rows = [r for r in rows if r and any(c.strip() for c in r)]
    if not rows:
        raise FileFormatError(f"recording {path}: empty; expected a header t,<joint>,...")
    header = [h.strip() for h in rows[0]]
    if header[0] != "t":
        raise FileFormatError(f"recording {path}: first column is {header[0]!r}; expected 't'")
    if len(set(header)) != len(header):
        raise FileFormatError(f"recording {path}: a column name appears twice in the header")
    _check_matched(header[1:], joint_names, f"recording {path}")
    cols = [header.index(n) if n in header else -1 for n in joint_names]
    body = rows[1:]
    if not body:
        raise FileFormatError(f"recording {path}: no samples after the header")
    t = np.empty(len(body))
    pos = np.full((len(body), len(joint_names)), np.nan)
    for r, row in enumerate(body):
        if len(row) != len(header):
            raise FileFormatError(
                f"recording {path}: line {r + 2} has {len(row)} cells; expected {len(header)}"
            )
        try:
            values = [float(c) for c in row]
        except ValueError:
            raise FileFormatError(f"recording {path}: line {r + 2}: a cell is not a number") from None
        bad = [header[i] for i, v in enumerate(values) if math.isinf(v) or (i == 0 and math.isnan(v))]
        if bad:
            raise FileFormatError(
                f"recording {path}: line {r + 2}: {bad[0]} is not finite "
                "(a missing position may be nan; infinity is never one)"
            )
        big = [header[c] for c in cols if c >= 0 and abs(values[c]) > MAX_ABS_POSITION_RAD]
        if big:
            raise FileFormatError(
                f"recording {path}: line {r + 2}: {big[0]} is {values[header.index(big[0])]:g} rad; "
                f"expected a joint position within ±{MAX_ABS_POSITION_RAD:g} rad"
            )
        t[r] = values[0]
        for j, c in enumerate(cols):
            if c >= 0:
                pos[r, j] = values[c]
    if np.any(np.diff(t) < 0):
        raise FileFormatError(f"recording {path}: column t is not in time order")
    return t, pos


def read_rosbag_recording(
    path: Path, joint_names: Sequence[str], topic: str = "/lite/joint_states"
) -> tuple[FloatArray, FloatArray]:
    """Read ``sensor_msgs/msg/JointState`` messages on ``topic`` from a rosbag2 (sqlite3 or mcap).

    Returns:
        ``(t (T,), positions (T, N))``; a joint absent from a message, or published as NaN, is NaN in that row.

    Raises:
        FileFormatError: Not a readable bag, no such topic (the message lists the topics), an infinite or
            too large position.
        JointMismatchError: No message names any of the joints.
    """
    require("rosbags", "reading rosbag2 recordings")
    from rosbags.highlevel import AnyReader

    bag = path
    if path.is_file() and path.suffix in (".db3", ".mcap"):
        bag = path.parent
    index = {n: i for i, n in enumerate(joint_names)}
    t: list[float] = []
    rows: list[FloatArray] = []
    seen: set[str] = set()
    try:
        with AnyReader([bag]) as reader:
            conns = [c for c in reader.connections if c.topic == topic]
            if not conns:
                topics = sorted({c.topic for c in reader.connections})
                listed = ", ".join(topics) or "none"
                raise FileFormatError(f"recording {path}: no topic {topic!r}; has {listed} (pass --topic)")
            bad = [c.msgtype for c in conns if c.msgtype != "sensor_msgs/msg/JointState"]
            if bad:
                raise FileFormatError(
                    f"recording {path}: topic {topic} has type {bad[0]}; expected JointState"
                )
            for conn, stamp_ns, raw in reader.messages(connections=conns):
                msg: Any = reader.deserialize(raw, conn.msgtype)
                row = np.full(len(joint_names), np.nan)
                for name, p in zip(msg.name, msg.position, strict=False):
                    seen.add(name)
                    i = index.get(name)
                    if i is not None and not math.isnan(p):
                        if math.isinf(p):
                            raise FileFormatError(
                                f"recording {path}: joint {name} is {p:g} at t = {stamp_ns * 1e-9:.9f} s; "
                                "not finite (a missing position may be NaN; infinity is never one)"
                            )
                        if abs(p) > MAX_ABS_POSITION_RAD:
                            raise FileFormatError(
                                f"recording {path}: joint {name} is {p:g} rad at t = {stamp_ns * 1e-9:.9f} s; "
                                f"expected a joint position within ±{MAX_ABS_POSITION_RAD:g} rad"
                            )
                        row[i] = p
                hs = msg.header.stamp
                ts = hs.sec + hs.nanosec * 1e-9 if (hs.sec or hs.nanosec) else stamp_ns * 1e-9
                t.append(ts)
                rows.append(row)
                if len(rows) > MAX_ROWS:
                    raise FileFormatError(f"recording {path}: more than {MAX_ROWS} messages")
    except FileFormatError:
        raise
    except Exception as exc:  # rosbags raises its own error types for unreadable bags
        raise FileFormatError(f"recording {path}: cannot read rosbag2 ({exc})") from None
    _check_matched(sorted(seen), joint_names, f"recording {path} topic {topic}")
    order = np.argsort(np.asarray(t), kind="stable")
    return np.asarray(t)[order], np.vstack(rows)[order]


def read_recording(
    path: Path, joint_names: Sequence[str], *, topic: str = "/lite/joint_states"
) -> tuple[FloatArray, FloatArray]:
    """Read a CSV or rosbag2 recording (chosen by the path: ``.csv`` → CSV, else rosbag2)."""
    if not path.exists():
        raise FileFormatError(f"recording {path}: no such file or folder")
    if path.suffix.lower() == ".csv":
        return read_csv_recording(path, joint_names)
    return read_rosbag_recording(path, joint_names, topic)
