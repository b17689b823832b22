"""The arm ``kinematics record`` reads: a LeRobot arm on a serial port (``sim`` / ``sim?…``: simulated), or a source.

:func:`open_reader` opens the one an :class:`ArmSource` names, with the URDF chain it reads.

The simulated arm is the one ``robocal lerobot … --port sim`` runs (the vendor SDK against simulated servos on a
pseudo-terminal, or with ``transport=inproc`` an in-process port); the LeRobot calibration the readings go
through is written to it first, as ``lerobot show --port sim`` does, so its readings are what a real arm with
that calibration would give. With a plan (``record --plan``) a simulated hand moves it to each planned pose
before the prompt, as a person would; without one nobody moves it and every pose reads where it rests.
"""

from __future__ import annotations

import math
import os
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from ...core.arrays import FloatArray
from ...core.chain import SerialChain
from ...core.jointmap import RobotCalibration
from ...errors import JointMismatchError, UsageError
from .record import JointReader, LeRobotReader, SourceReader, calibration_for_chain, lerobot_joint_map

__all__ = [
    "SIM_PORT_OPTIONS",
    "ArmSource",
    "check_session",
    "lerobot_calibration_path",
    "open_reader",
    "open_record_bus",
]

SIM_PORT_OPTIONS = ("seed", "transport")
"""What ``--lerobot-port sim?…`` takes: the read-noise seed and ``transport=pty|inproc``."""


def check_session(
    kind: str, out: str | os.PathLike[str], arm: ArmSource | None = None, plan: str | os.PathLike[str] | None = None
) -> Path:
    """``--kind`` and ``--out`` of a session, checked before the arm is opened (a LeRobot arm goes limp then).

    ``--out`` may be none of the session's input files (``arm``'s URDF, calibration file, joint map or replayed
    recording, the ``plan``).

    Raises:
        UsageError: An unknown kind, an output in a missing folder, on a directory or on an input.
    """
    from ...backends.sources import recording_path
    from ...core.kinematic_problem import ALL_KINDS, check_kind
    from ...fileio import check_output_path

    check_kind(kind, ALL_KINDS)
    inputs = {"--plan": plan}
    if arm is not None:
        inputs |= {"--urdf": arm.urdf, "--file": arm.calibration_file, "--joint-map": arm.joint_map,
                   "--source": recording_path(arm.source)}  # fmt: skip
    return check_output_path(out, "--out", inputs=inputs)


def lerobot_calibration_path(
    spec: Any,
    robot_id: str | None,
    calibration_dir: str | os.PathLike[str] | None,
    calibration_file: str | os.PathLike[str] | None,
) -> Path | None:
    """The LeRobot calibration JSON of ``--id`` (found as LeRobot finds it) or ``--file``; None without both."""
    from ..lerobot import calibration_file as find_calibration_file

    if calibration_file is None and robot_id is None:
        return None
    path, _note = find_calibration_file(
        spec,
        robot_id,
        Path(calibration_dir) if calibration_dir is not None else None,
        Path(calibration_file) if calibration_file is not None else None,
    )
    return path


Hand = Callable[[FloatArray], None]
"""Moves a simulated arm so that it reads the given chain joint positions (rad)."""


def open_record_bus(
    spec: Any, port: str, calibration: Path | None, motor_ids: list[int], joint_map: RobotCalibration
) -> tuple[Any, Callable[[], None], Hand | None]:
    """Open the arm's bus on ``port`` (``sim``/``sim?seed=N&transport=inproc``: a simulated arm first).

    Args:
        spec: The arm's :class:`~robocal.core.lerobot.RobotSpec`.
        port: A serial port, or ``sim`` with options :data:`SIM_PORT_OPTIONS`.
        calibration: The LeRobot calibration the readings go through (written to a simulated arm), or None.
        motor_ids: Bus id per chain joint, in chain order.
        joint_map: ``q = direction·scale·(Present_Position − homing_offset)`` per chain joint, in chain order.

    Returns:
        The open bus, the function that closes it (and stops a simulated arm), and on a simulated arm the hand
        that moves it to a pose (None on a real port).

    Raises:
        UsageError: Bad ``sim`` options.
        DeviceError: The port cannot be opened.
    """
    from ..lerobot import open_bus, open_sim_bus

    if port != "sim" and not port.startswith("sim?"):
        bus = open_bus(spec, port)
        return bus, bus.close, None
    from ...backends.sim.lerobot_arms import SimArm
    from ...backends.sources.spec import parse_sim_options
    from ..lerobot import restore
    from ..lerobot.arms import check_simulated

    check_simulated(spec, port, "--lerobot-port")

    opts = parse_sim_options(port, port.partition("?")[2], SIM_PORT_OPTIONS)
    transport = opts.get("transport", "pty")
    if transport not in ("pty", "inproc"):
        raise UsageError(f"--lerobot-port {port!r}: transport {transport!r}: expected pty or inproc")
    cals = None
    if calibration is not None:
        from ..lerobot import read_calibration_file

        cals = read_calibration_file(calibration)
    arm = SimArm(spec, seed=int(opts.get("seed", "0")), noise_ticks=1, transport=transport).start()
    try:
        bus = open_sim_bus(spec, arm, port)
    except BaseException:
        arm.stop()
        raise

    def close() -> None:
        try:
            bus.close()
        finally:
            arm.stop()

    try:
        if cals is not None:
            restore(bus, spec, cals)
    except BaseException:
        close()
        raise

    def reach(servo: Any, present: int) -> float:
        """The shaft position that reads ``present``, on the turn inside the hard stops where there is one."""
        a = servo.goal_to_actual(present)
        inside = [a + k * servo.resolution for k in (0, -1, 1)]
        inside = [v for v in inside if servo.stop_low_ticks <= v <= servo.stop_high_ticks]
        return float(inside[0]) if inside else float(a)

    def hand(q_rad: FloatArray) -> None:
        present = np.rint(np.asarray(joint_map.to_raw(np.asarray(q_rad, dtype=np.float64)), dtype=np.float64))
        arm.bus.move({i: reach(arm.bus.servos[i], int(p)) for i, p in zip(motor_ids, present, strict=True)})

    return bus, close, hand


@dataclass(frozen=True)
class ArmSource:
    """Where ``kinematics record`` reads the joints from, and the URDF chain it reads.

    Attributes:
        urdf: Expanded URDF (default for ``robot`` ``so101_*`` / ``koch_*``: the shipped one).
        base_link: First link of the chain (default: the URDF root).
        tip_link: Last link of the chain (default: the only leaf, or the shipped arm's).
        lerobot_port: Serial port of a LeRobot arm (``sim`` for a simulated one); or give ``source``.
        robot: The LeRobot arm type (``so101_follower``, ``koch_leader``, ...).
        robot_id: LeRobot id of its calibration.
        calibration_dir: LeRobot calibration root (default: LeRobot's).
        calibration_file: The LeRobot calibration JSON (instead of ``robot_id``).
        source: Any robocal source (``sim:lite``, ``can:<if>:<ch>``, ``replay:<file>``); or give ``lerobot_port``.
        joint_map: Raw → URDF joint map (``lerobot export-urdf`` output, or any calibration file for ``source``).

    Raises:
        UsageError: Neither or both of ``lerobot_port`` and ``source``.
    """

    urdf: str | os.PathLike[str] | None = None
    base_link: str | None = None
    tip_link: str | None = None
    lerobot_port: str | None = None
    robot: str | None = None
    robot_id: str | None = None
    calibration_dir: str | os.PathLike[str] | None = None
    calibration_file: str | os.PathLike[str] | None = None
    source: str | None = None
    joint_map: str | os.PathLike[str] | None = None

    def __post_init__(self) -> None:
        if (self.lerobot_port is None) == (self.source is None):
            raise UsageError("give either --lerobot-port (with --robot) or --source")


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


def open_reader(arm: ArmSource) -> tuple[JointReader, SerialChain]:
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

    lerobot_port, robot, source, joint_map = arm.lerobot_port, arm.robot, arm.source, arm.joint_map
    chain, urdf_model = _chain(arm.urdf, arm.base_link, arm.tip_link, robot)
    file_map = None
    if joint_map is not None:
        file_map = calibration_for_chain(
            read_calibration(joint_map).calibration, chain, f"--joint-map {joint_map}"
        )
    if lerobot_port is not None:
        from ..lerobot import robot_spec

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
            lerobot_joint_map(spec, arm.robot_id, arm.calibration_dir, arm.calibration_file), chain, f"{robot} calibration"
        )
        motor_ids = [ids[n] for n in chain.joint_names]
        cal_path = lerobot_calibration_path(spec, arm.robot_id, arm.calibration_dir, arm.calibration_file)
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
