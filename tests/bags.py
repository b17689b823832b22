"""One rosbag2 writer of ``sensor_msgs/JointState`` messages (rosbags), for the replay and fuzz tests."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import numpy as np
from numpy.typing import ArrayLike


def write_joint_states(
    path: Path,
    names: Sequence[str],
    stamps_s: ArrayLike,
    positions: ArrayLike,
    *,
    plugin: str = "mcap",
    topic: str = "/lite/joint_states",
    receive_s: ArrayLike | None = None,
) -> None:
    """Write a rosbag2 (``mcap`` or ``sqlite3``) of JointState messages, one per row of ``positions``.

    Message ``i`` has the header stamp ``stamps_s[i]`` + 1 s and is recorded at ``receive_s[i]`` + 1 s (default:
    at its stamp); velocity and effort are empty.
    """
    from rosbags.rosbag2 import StoragePlugin, Writer
    from rosbags.typesys import Stores, get_typestore

    ts = get_typestore(Stores.ROS2_HUMBLE)
    joint_state = ts.types["sensor_msgs/msg/JointState"]
    header = ts.types["std_msgs/msg/Header"]
    time_t = ts.types["builtin_interfaces/msg/Time"]
    stamps = np.asarray(stamps_s, dtype=np.float64)
    received = stamps if receive_s is None else np.asarray(receive_s, dtype=np.float64)
    storage = StoragePlugin.MCAP if plugin == "mcap" else StoragePlugin.SQLITE3
    with Writer(path, version=8, storage_plugin=storage) as w:
        conn = w.add_connection(topic, joint_state.__msgtype__, typestore=ts)
        for tr, st, row in zip(received, stamps, positions, strict=True):
            ns = round(st * 1e9) + 1_000_000_000
            msg = joint_state(
                header=header(stamp=time_t(sec=ns // 10**9, nanosec=ns % 10**9), frame_id=""),
                name=list(names),
                position=np.asarray(row, dtype=np.float64),
                velocity=np.zeros(0),
                effort=np.zeros(0),
            )
            w.write(conn, round(tr * 1e9) + 1_000_000_000, ts.serialize_cdr(msg, joint_state.__msgtype__))
