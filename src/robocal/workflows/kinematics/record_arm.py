"""The LeRobot arm ``kinematics record`` reads: a serial port, or ``sim`` / ``sim?…`` for a simulated arm.

The simulated arm is the one ``robocal lerobot … --port sim`` runs (the vendor SDK against simulated servos on a
pseudo-terminal, or with ``transport=inproc`` an in-process port); the LeRobot calibration the readings go
through is written to it first, as ``lerobot show --port sim`` does, so its readings are what a real arm with
that calibration would give. With a plan (``record --plan``) a simulated hand moves it to each planned pose
before the prompt, as a person would; without one nobody moves it and every pose reads where it rests.
"""

from __future__ import annotations

import os
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from ...core.arrays import FloatArray
from ...core.jointmap import RobotCalibration
from ...errors import UsageError

__all__ = ["SIM_PORT_OPTIONS", "check_session", "lerobot_calibration_path", "open_record_bus"]

SIM_PORT_OPTIONS = ("seed", "transport")
"""What ``--lerobot-port sim?…`` takes: the read-noise seed and ``transport=pty|inproc``."""


def check_session(kind: str, out: str | os.PathLike[str]) -> Path:
    """``--kind`` and ``--out`` of a session, checked before the arm is opened (a LeRobot arm goes limp then).

    Raises:
        UsageError: An unknown kind, an output in a missing folder or on a directory.
    """
    from ...core.kinematic_problem import ALL_KINDS, check_kind
    from ...fileio import check_output_path

    check_kind(kind, ALL_KINDS)
    return check_output_path(out, "--out")


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
    from ..lerobot import open_bus

    if port != "sim" and not port.startswith("sim?"):
        bus = open_bus(spec, port)
        return bus, bus.close, None
    from ...backends.sim.lerobot_arms import SimArm
    from ...backends.sources.spec import parse_sim_options
    from ..lerobot import restore

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
        bus = open_bus(spec, arm.port)
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
