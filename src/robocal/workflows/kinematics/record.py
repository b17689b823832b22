"""Record a kinematic identification session: the user poses the arm by hand and presses Enter per pose.

Joint readings come from a LeRobot arm on its servo bus (Present_Position through the LeRobot calibration and
the ``q_urdf = sign·q + offset`` map of ``robocal lerobot export-urdf``) or from any robocal ``--source``
(through an optional joint-map calibration file). For each pose the recorder asks for the measurement columns
the chosen kind needs (the tracker's ``x y z``, the touched point's label, the gauge socket, the tag image) and
writes, once the session ends, the CSV that ``robocal kinematics identify --data`` reads. Nothing moves: a LeRobot
arm's torque is switched off first so it can be moved by hand.
"""

from __future__ import annotations

import math
import os
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Protocol

import numpy as np

from ...core.arrays import FloatArray
from ...core.chain import SerialChain
from ...core.jointmap import RobotCalibration
from ...core.kinematic_problem import ALL_KINDS, Measurements, check_kind
from ...errors import JointMismatchError, UsageError
from ...fileio import atomic_write_text, check_output_path
from ...formats._numbers import format_float
from ...formats.kinematic_data import session_csv

__all__ = [
    "JointReader",
    "LeRobotReader",
    "RecordRequest",
    "RecordResult",
    "SourceReader",
    "calibration_for_chain",
    "lerobot_joint_map",
    "plan_targets",
    "record",
]



FINISH_WORDS = ("q", "quit", "done", "end")


class JointReader(Protocol):
    """Reads the chain's joints (rad, or m for prismatic joints) in chain order."""

    joint_names: tuple[str, ...]

    def read(self) -> FloatArray:
        """One reading, ``(n_q,)``."""
        ...

    def close(self) -> None:
        """Release the bus or source."""
        ...


def calibration_for_chain(calibration: RobotCalibration, chain: SerialChain, what: str) -> RobotCalibration:
    """The joint map restricted to the chain's movable joints, in chain order.

    Raises:
        JointMismatchError: A chain joint the joint map does not have (names the joints it has).
    """
    missing = [n for n in chain.joint_names if n not in calibration]
    if missing:
        raise JointMismatchError(
            f"{what} has no joint(s) {', '.join(missing)} of the chain; it has {', '.join(calibration.joint_names)}"
        )
    return calibration.select(chain.joint_names)


class LeRobotReader:
    """Present_Position of a LeRobot arm's motors mapped to URDF joint angles.

    Args:
        bus: An open :class:`~robocal.backends.servo_bus.ServoBus` of the arm.
        motor_ids: Bus id per chain joint, in chain order.
        joint_map: ``q_urdf = direction·scale·(Present_Position − homing_offset)`` per chain joint (the map of
            ``robocal lerobot export-urdf``), in chain order.
        samples: Readings averaged per pose (the servo's read noise averages out).
        close: Closes the bus (and stops a simulated arm); default ``bus.close``.
        hand: A simulated arm's hand: moves it to a pose before the prompt (``record`` with a plan).
    """

    def __init__(
        self,
        bus: Any,
        motor_ids: Sequence[int],
        joint_map: RobotCalibration,
        *,
        samples: int = 5,
        close: Callable[[], None] | None = None,
        hand: Callable[[FloatArray], None] | None = None,
    ) -> None:
        self.bus = bus
        self.hand = hand
        self._close = bus.close if close is None else close
        self.motor_ids = [int(i) for i in motor_ids]
        self.joint_map = joint_map
        self.joint_names = joint_map.joint_names
        self.samples = max(1, samples)

    def read(self) -> FloatArray:
        """Mean of ``samples`` sync reads of Present_Position, as URDF joint positions."""
        rows = []
        for _ in range(self.samples):
            got = self.bus.sync_read("Present_Position", self.motor_ids)
            rows.append([float(got[i]) for i in self.motor_ids])
        return np.asarray(self.joint_map.to_joint(np.mean(rows, axis=0)), dtype=np.float64)

    def close(self) -> None:
        """Close the bus (and stop a simulated arm)."""
        self._close()


class SourceReader:
    """The latest sample of a robocal joint source, through an optional joint map.

    Args:
        source: An open :class:`~robocal.backends.sources.Source` over the chain's joints (chain order).
        joint_map: Maps the source's positions to joint positions (None: used as they are).
    """

    def __init__(self, source: Any, joint_map: RobotCalibration | None) -> None:
        self.source = source
        self.joint_map = joint_map
        self.joint_names = tuple(source.joint_names)

    def read(self) -> FloatArray:
        """One sample of every joint; a source that has run out is an error."""
        sample = self.source.read()
        if sample is None:
            raise UsageError("the source has no more samples (end of the recording)")
        pos = np.asarray(sample.position_rad, dtype=np.float64)
        return pos if self.joint_map is None else np.asarray(self.joint_map.to_joint(pos), dtype=np.float64)

    def close(self) -> None:
        """Close the source."""
        self.source.close()


@dataclass(frozen=True, eq=False)
class RecordResult:
    """What a recording session produced.

    Attributes:
        out: The CSV written.
        measurements: The session (tag sessions: joint readings only, ``kind`` ``points`` with NaN-free zeros).
        images: Image path per pose (``tag`` only), as written in the CSV.
        skipped: Messages about poses that were not recorded.
        interrupted: True when the session ended with Ctrl-C (the poses so far were written).
    """

    out: Path
    measurements: Measurements
    images: tuple[str, ...] = ()
    skipped: tuple[str, ...] = field(default_factory=tuple)
    interrupted: bool = False


Ask = Callable[[str], str]
Say = Callable[[str], None]


def _ask_xyz(ask: Ask, pose: int) -> FloatArray | None:
    """``x y z`` in millimetres from the user; None when they give up (empty answer twice is not asked)."""
    for _ in range(3):
        text = ask(f"pose {pose}: marker position x y z in mm (from the tracker)")
        parts = [p for p in text.replace(",", " ").split() if p]
        try:
            values = [float(p) for p in parts]
        except ValueError:
            values = []
        if len(values) == 3 and all(math.isfinite(v) for v in values):
            return np.asarray(values, dtype=np.float64) * 1e-3
    return None


def _joint_text(chain: SerialChain, k: int, value: float) -> str:
    """A joint value as a user reads it: degrees for rotations, millimetres for prismatic joints."""
    if chain.movable[k].type == "prismatic":
        return f"{value * 1e3:+.1f} mm"
    return f"{math.degrees(value):+.1f}°"


def _target_text(chain: SerialChain, q: FloatArray) -> str:
    return ", ".join(f"{name} {_joint_text(chain, k, float(q[k]))}" for k, name in enumerate(chain.joint_names))


@dataclass(frozen=True, eq=False)
class RecordRequest:
    """A recording session of ``kinematics record``: what to write and what to ask per pose (checked when built).

    Attributes:
        out: CSV to write (atomically, at the end; also after Ctrl-C when poses were recorded).
        kind: ``points``, ``touch``, ``gauge`` or ``tag``.
        poses: Stop after this many poses (None: until the user finishes).
        image_pattern: Default image path per pose (``{pose}`` is the pose number), relative to the CSV.
        targets: ``(N, n_q)`` planned poses (``kinematics plan``): pose ``n``'s prompt shows target ``n``, and
            its reading is compared with it; ``poses`` defaults to ``N``.
        target_labels: The point each planned pose touches (``touch``: its label, ``gauge``: ``A``/``B``):
            named in the prompt and taken when the answer is empty.

    Raises:
        UsageError: An unknown kind, ``poses`` below 1.
    """

    out: str | os.PathLike[str]
    kind: str = "points"
    poses: int | None = None
    image_pattern: str = "pose_{pose:03d}.png"
    targets: FloatArray | None = None
    target_labels: Sequence[str] = ()

    def __post_init__(self) -> None:
        check_kind(self.kind, ALL_KINDS)
        if self.poses is not None and self.poses < 1:
            raise UsageError(f"--poses must be at least 1, got {self.poses}")


def record(reader: JointReader, chain: SerialChain, request: RecordRequest, *, ask: Ask, say: Say) -> RecordResult:
    """Run a recording session and write the measurement CSV.

    Each pose: ``ask`` waits for Enter (an answer ``q``/``done``, or end of input, finishes), the joints are
    read, checked against the URDF limits (a pose outside them is not recorded, with a message), then the
    kind's columns are asked for: ``points`` ``x y z`` in mm, ``touch`` the contact point's label (Enter keeps
    the previous one), ``gauge`` the socket ``A``/``B``, ``tag`` the image file (Enter: ``image_pattern``).

    Args:
        reader: Where the joint readings come from (chain order).
        chain: The URDF chain (joint names, limits).
        request: The session (checked when it was built).
        ask: Shows a prompt and returns the user's line (raises ``EOFError`` at the end of input).
        say: Shows a message.

    Returns:
        The :class:`RecordResult`.

    Raises:
        JointMismatchError: The reader's joints are not the chain's, or the plan's shape does not fit.
        UsageError: An output in a missing folder, or no pose recorded (nothing is written).
    """
    kind, poses, image_pattern, targets = request.kind, request.poses, request.image_pattern, request.targets
    target_labels = request.target_labels
    if tuple(reader.joint_names) != chain.joint_names:
        raise JointMismatchError(
            f"the reader gives {', '.join(reader.joint_names)}; the chain needs {', '.join(chain.joint_names)}"
        )
    out_path = check_output_path(request.out, "--out")
    if targets is not None:
        targets = np.atleast_2d(np.asarray(targets, dtype=np.float64))
        if targets.shape[1:] != (chain.n_q,) or targets.shape[0] == 0:
            raise JointMismatchError(f"the plan has shape {targets.shape}; expected (N, {chain.n_q}) poses")
        poses = targets.shape[0] if poses is None else poses
    qs: list[FloatArray] = []
    points: list[FloatArray] = []
    labels: list[str] = []
    groups: list[int] = []
    images: list[str] = []
    skipped: list[str] = []
    interrupted = False
    last_label = "P1"
    lo, up = chain.limits()
    try:
        while poses is None or len(qs) < poses:
            n = len(qs) + 1
            try:
                goal = "" if targets is None or n > len(targets) else f" to {_target_text(chain, targets[n - 1])}"
                planned = target_labels[n - 1] if n <= len(target_labels) else ""
                goal += f", touching {planned}" if planned and kind in ("touch", "gauge") else ""
                hand = getattr(reader, "hand", None)  # a simulated arm: moved as a person would move it
                if hand is not None and targets is not None and n <= len(targets):
                    hand(targets[n - 1])
                answer = ask(f"pose {n}: move the arm{goal}, then press Enter (q + Enter when done)")
            except EOFError:
                break
            if answer.strip().lower() in FINISH_WORDS:
                break
            q = reader.read()
            bad = ~np.isfinite(q)
            if bad.any():
                msg = (
                    f"pose {n}: joint {chain.joint_names[int(np.argmax(bad))]} gave no reading; not recorded"
                )
                skipped.append(msg)
                say(msg)
                continue
            outside = (q < lo - 1e-9) | (q > up + 1e-9)
            if outside.any():
                k = int(np.argmax(outside))
                msg = (
                    f"pose {n}: joint {chain.joint_names[k]} = {q[k]:.4g} is outside its URDF limits "
                    f"[{lo[k]:.4g}, {up[k]:.4g}]; not recorded (check the calibration or move it back)"
                )
                skipped.append(msg)
                say(msg)
                continue
            try:
                if kind == "points":
                    p = _ask_xyz(ask, n)
                    if p is None:
                        msg = f"pose {n}: no valid x y z given; not recorded"
                        skipped.append(msg)
                        say(msg)
                        continue
                    points.append(p)
                elif kind == "touch":
                    last_label = planned or last_label
                    label = ask(f"pose {n}: label of the touched point [{last_label}]").strip() or last_label
                    last_label = label
                    if label not in labels:
                        labels.append(label)
                    groups.append(labels.index(label))
                elif kind == "gauge":
                    while True:
                        prompt = f"pose {n}: ball in socket A or B" + (f" [{planned}]" if planned else "")
                        socket = ask(prompt).strip().upper() or planned.upper()
                        if socket in ("A", "B"):
                            break
                        say(f"socket {socket!r}: answer A or B")
                    groups.append(0 if socket == "A" else 1)
                else:
                    default = image_pattern.format(pose=n)
                    images.append(ask(f"pose {n}: image file [{default}]").strip() or default)
            except EOFError:
                break
            qs.append(q)
            off = ""
            if targets is not None and n <= len(targets):
                k = int(np.argmax(np.abs(q - targets[n - 1])))
                off = f" (off the plan by at most {_joint_text(chain, k, q[k] - targets[n - 1][k])}, {chain.joint_names[k]})"
            say(
                f"pose {n} recorded: "
                + ", ".join(f"{name} {v:+.4f}" for name, v in zip(chain.joint_names, q, strict=True))
                + off
            )
    except KeyboardInterrupt:
        interrupted = True
        if not qs:
            raise
    if not qs:
        raise UsageError("no pose was recorded; nothing written")
    q_arr = np.asarray(qs, dtype=np.float64)
    if kind == "points":
        data = Measurements("points", q_arr, np.asarray(points))
        assert data.p_world_m is not None
        extra = {c: [format_float(float(v)) for v in data.p_world_m[:, a]] for a, c in enumerate("xyz")}
    elif kind == "tag":
        data = Measurements("points", q_arr, np.zeros((len(qs), 3)))
        extra = {"image": images}
    else:
        data = Measurements("touch", q_arr, group=np.asarray(groups))
        if kind == "gauge":
            if set(groups) != {0, 1}:
                say(
                    "warning: a gauge session needs poses in both socket A and socket B; record the other one too"
                )
            extra = {"socket": ["A" if g == 0 else "B" for g in groups]}
        else:
            extra = {"group": [labels[g] for g in groups]}
    text = session_csv(q_arr, chain.joint_names, extra)
    written = atomic_write_text(out_path, text)
    return RecordResult(written, data, tuple(images), tuple(skipped), interrupted)


def lerobot_joint_map(
    spec: Any,
    robot_id: str | None,
    calibration_dir: str | os.PathLike[str] | None,
    calibration_file: str | os.PathLike[str] | None,
) -> RobotCalibration:
    """The ``lerobot export-urdf`` map (sign +1, offset 0) of an arm's LeRobot calibration file.

    Args:
        spec: The arm's :class:`~robocal.core.lerobot.RobotSpec`.
        robot_id: LeRobot id (the file is found like LeRobot does, pre-v0.4.3 folder as a fallback).
        calibration_dir: LeRobot calibration root (default: LeRobot's).
        calibration_file: The JSON itself (instead of ``robot_id``).
    """
    from ..lerobot import calibration_file as find_calibration_file
    from ..lerobot import export_joint_map, read_calibration_file

    if calibration_file is None and robot_id is None:
        raise UsageError("give --id (and optionally --calibration-dir), --file or --joint-map")
    path, _note = find_calibration_file(
        spec,
        robot_id,
        Path(calibration_dir) if calibration_dir is not None else None,
        Path(calibration_file) if calibration_file is not None else None,
    )
    joint_map, _ = export_joint_map(spec, read_calibration_file(path))
    return joint_map


def plan_targets(plan: str | os.PathLike[str], chain: SerialChain) -> tuple[FloatArray, tuple[str, ...]]:
    """The poses of a ``kinematics plan`` CSV for ``chain`` (checked against its limits), and their labels."""
    from ...formats.kinematic_data import read_pose_plan

    targets, labels = read_pose_plan(plan, chain.joint_names)
    return chain.check_q(targets, what=f"{plan}: pose"), labels
