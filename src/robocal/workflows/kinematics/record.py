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
    "RecordResult",
    "SourceReader",
    "calibration_for_chain",
    "lerobot_joint_map",
    "open_reader",
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


def record(
    reader: JointReader,
    chain: SerialChain,
    out: str | os.PathLike[str],
    *,
    kind: str = "points",
    ask: Ask,
    say: Say,
    poses: int | None = None,
    image_pattern: str = "pose_{pose:03d}.png",
    targets: FloatArray | None = None,
    target_labels: Sequence[str] = (),
) -> RecordResult:
    """Run a recording session and write the measurement CSV.

    Each pose: ``ask`` waits for Enter (an answer ``q``/``done``, or end of input, finishes), the joints are
    read, checked against the URDF limits (a pose outside them is not recorded, with a message), then the
    kind's columns are asked for: ``points`` ``x y z`` in mm, ``touch`` the contact point's label (Enter keeps
    the previous one), ``gauge`` the socket ``A``/``B``, ``tag`` the image file (Enter: ``image_pattern``).

    Args:
        reader: Where the joint readings come from (chain order).
        chain: The URDF chain (joint names, limits).
        out: CSV to write (atomically, at the end; also after Ctrl-C when poses were recorded).
        kind: ``points``, ``touch``, ``gauge`` or ``tag``.
        ask: Shows a prompt and returns the user's line (raises ``EOFError`` at the end of input).
        say: Shows a message.
        poses: Stop after this many poses (None: until the user finishes).
        image_pattern: Default image path per pose (``{pose}`` is the pose number), relative to the CSV.
        targets: ``(N, n_q)`` planned poses (``kinematics plan``): pose ``n``'s prompt shows target ``n``, and
            its reading is compared with it; ``poses`` defaults to ``N``.
        target_labels: The point each planned pose touches (``touch``: its label, ``gauge``: ``A``/``B``):
            named in the prompt and taken when the answer is empty.

    Returns:
        The :class:`RecordResult`.

    Raises:
        UsageError: Bad options, or no pose recorded (nothing is written).
    """
    check_kind(kind, ALL_KINDS)
    if poses is not None and poses < 1:
        raise UsageError(f"--poses must be at least 1, got {poses}")
    if tuple(reader.joint_names) != chain.joint_names:
        raise JointMismatchError(
            f"the reader gives {', '.join(reader.joint_names)}; the chain needs {', '.join(chain.joint_names)}"
        )
    out_path = check_output_path(out, "--out")
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


def _chain(
    urdf: str | os.PathLike[str] | None, base_link: str | None, tip_link: str | None, robot: str | None
) -> tuple[SerialChain, Any]:
    from ...formats.urdf import UrdfDocument
    from ...formats.urdf_chain import chain_from_urdf
    from .sim import SIM_ROBOTS, shipped_urdf

    if urdf is None:
        family = (robot or "").split("_")[0]
        if family not in SIM_ROBOTS:
            raise UsageError("give --urdf (robocal ships URDFs only for so101_* and koch_* arms)")
        urdf = shipped_urdf(family)
        tip_link = tip_link or SIM_ROBOTS[family].tip_link
    model = UrdfDocument.load(urdf).model()
    return chain_from_urdf(model, base_link, tip_link), model


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


def open_reader(
    *,
    urdf: str | os.PathLike[str] | None = None,
    base_link: str | None = None,
    tip_link: str | None = None,
    lerobot_port: str | None = None,
    robot: str | None = None,
    robot_id: str | None = None,
    calibration_dir: str | os.PathLike[str] | None = None,
    calibration_file: str | os.PathLike[str] | None = None,
    source: str | None = None,
    joint_map: str | os.PathLike[str] | None = None,
) -> tuple[JointReader, SerialChain]:
    """Open the joint reader of ``kinematics record`` and the URDF chain it reads.

    LeRobot (``lerobot_port`` + ``robot``): the map is ``joint_map`` (a ``lerobot export-urdf`` file) or, without
    it, the export-urdf map with sign +1 and offset 0 of the LeRobot calibration (``robot_id`` or
    ``calibration_file``); every motor's torque is switched off. ``source``: any robocal source over the chain's
    joints, through ``joint_map`` when given.

    Raises:
        UsageError: Options missing or contradictory.
        JointMismatchError: A chain joint the arm, the source or the joint map does not have.
    """
    from ...formats import read_calibration

    if (lerobot_port is None) == (source is None):
        raise UsageError("give either --lerobot-port (with --robot) or --source")
    chain, urdf_model = _chain(urdf, base_link, tip_link, robot)
    file_map = None
    if joint_map is not None:
        file_map = calibration_for_chain(
            read_calibration(joint_map).calibration, chain, f"--joint-map {joint_map}"
        )
    if lerobot_port is not None:
        from ..lerobot import robot_spec
        from .record_arm import lerobot_calibration_path, open_record_bus

        if robot is None:
            raise UsageError("--lerobot-port needs --robot (so101_follower, koch_leader, ...)")
        spec = robot_spec(robot)
        ids = {m.name: m.motor_id for m in spec.motors}
        missing = [n for n in chain.joint_names if n not in ids]
        if missing:
            raise JointMismatchError(
                f"{robot} has no motor(s) {', '.join(missing)}; its motors are {', '.join(ids)}: a LeRobot arm is "
                "read by motor name, so the URDF's chain joints must carry those names (give --urdf with them)"
            )
        jm = file_map or calibration_for_chain(
            lerobot_joint_map(spec, robot_id, calibration_dir, calibration_file), chain, f"{robot} calibration"
        )
        motor_ids = [ids[n] for n in chain.joint_names]
        cal_path = lerobot_calibration_path(spec, robot_id, calibration_dir, calibration_file)
        bus, close, hand = open_record_bus(spec, lerobot_port, cal_path, motor_ids, jm)
        try:
            for m in spec.motors:  # limp: the user moves the arm by hand
                bus.write("Torque_Enable", m.motor_id, 0)
        except BaseException:
            close()
            raise
        return LeRobotReader(bus, motor_ids, jm, close=close, hand=hand), chain
    from ...backends.sources import JointSpec, open_source

    assert source is not None
    specs = []
    lows, ups = chain.limits()
    for j, lo, up in zip(chain.movable, lows, ups, strict=True):
        specs.append(
            JointSpec(
                j.name,
                urdf_model.motor_id(j.name) or 0,
                urdf_model.param(j.name, "model") or "rs-00",
                urdf_model.direction(j.name) or 1,
                float(lo) if math.isfinite(lo) else -math.pi,
                float(up) if math.isfinite(up) else math.pi,
            )
        )
    src = open_source(source, specs)
    return SourceReader(src, file_map), chain
