"""Joint-position sources for the sweep: a simulated Lite, live Robstride CAN buses, or a recording.

Source strings (``--source``):

* ``sim:lite`` or ``sim:lite?seed=N&noise=R&skip=a,b&short=joint:R&flip=a&zero_sta=1&single_turn=1`` — the
  simulated Lite bimanual robot with its simulated operator (see :mod:`robocal.backends.sim.lite`).
* ``sim:openarm[?seed=N&zeroed=1]`` — one simulated OpenArm arm (the joints' side) whose simulated hands sweep
  every joint into both stops, read through the Damiao bus (:mod:`.damiao`).
* ``can:<interface>:<channel>[,<channel>…]`` — live Robstride motors, e.g. ``can:socketcan:can0,can1``; each
  joint is found on the channel where its CAN id answers.
* ``replay:<file>`` — a CSV (``t,<joint>,…``) or a rosbag2 folder/file (sqlite3 or mcap) of
  ``sensor_msgs/msg/JointState``.

A source yields :class:`Sample` rows in its :attr:`frame`: ``"motor"`` (raw motor positions, what the buses
read) or ``"identity"`` (``direction·raw``, what a robot publishes with an empty calibration file).
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

from ..replay import DEFAULT_TOPIC
from .can import RobstrideSource, SimLiteSource, open_can, open_sim_lite_source
from .recording import ReplaySource, StreamReplaySource
from .spec import (
    REPLAY_FRAMES,
    SIM_OPTIONS,
    JointSpec,
    Sample,
    Source,
    SourceSpec,
    check_replay_frame,
    parse_source,
    recording_path,
)

__all__ = [
    "DEFAULT_TOPIC",
    "REPLAY_FRAMES",
    "SIM_OPTIONS",
    "JointSpec",
    "ReplaySource",
    "RobstrideSource",
    "Sample",
    "SimLiteSource",
    "Source",
    "SourceSpec",
    "StreamReplaySource",
    "check_replay_frame",
    "open_source",
    "parse_source",
    "recording_path",
]


def open_source(
    spec: SourceSpec | str,
    joints: Sequence[JointSpec],
    *,
    topic: str = DEFAULT_TOPIC,
    frame: str | None = None,
    timeout_s: float = 0.1,
) -> Source:
    """Open a source for ``joints``.

    Args:
        spec: A parsed or raw ``--source``.
        joints: Joints in URDF order.
        topic: JointState topic for rosbag2 replays.
        frame: Frame of a replay's positions (``identity`` default, or ``motor``); live sources are ``motor``.
        timeout_s: Per-request timeout for live buses, s.

    Returns:
        The open source (close it when done).
    """
    if isinstance(spec, str):
        spec = parse_source(spec)
    check_replay_frame(frame)
    if spec.kind == "sim" and spec.robot == "openarm":
        from .damiao import open_sim_openarm_source

        return open_sim_openarm_source(spec, joints)
    if spec.kind == "sim":
        return open_sim_lite_source(spec, joints)
    if spec.kind == "can":
        return open_can(spec, joints, timeout_s)
    from ..replay import open_recording

    names = [j.name for j in joints]
    recording = open_recording(Path(spec.path), names, topic=topic)
    return StreamReplaySource(names, recording, frame or "identity")
