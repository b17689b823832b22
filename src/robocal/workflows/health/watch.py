"""``robocal health watch``: the live monitor on a LeRobot arm's bus or a ``--source``, read-only.

Reads the joints as fast as ``rate_hz`` allows, maps them into the calibrated frame and feeds
:class:`robocal.core.health.Monitor`; every flag goes to the caller as it happens. Nothing is written: a LeRobot
arm is only read (``Present_Position`` by SYNC_READ), a ``--source`` only sampled. The one exception is
``--lerobot-port sim``: the simulated arm starts uncalibrated and is given the calibration first (as
``lerobot show`` does); a real port, a simulator's own port or a source is never written.
"""

from __future__ import annotations

import contextlib
import math
import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ...core.arrays import FloatArray
from ...core.health import HealthFlag, Monitor, MonitorConfig, monitor_config
from ...errors import FileFormatError, UsageError

__all__ = ["WatchRequest", "WatchResult", "watch"]

_MIN_RATE_HZ = 1e-3
"""Fewest readings per second ``--rate-hz`` takes (a longer pause overflows ``time.sleep``: 1e-300 did)."""


@dataclass(frozen=True)
class WatchRequest:
    """What to watch and how (checked when built).

    Attributes:
        lerobot_port: A LeRobot arm's serial port (or ``sim``), with ``robot``; or None with ``source``.
        robot: The LeRobot robot profile (``so101_follower`` ...) for ``lerobot_port``; the robot profile of a
            ``source`` (optional: recognised from the URDF).
        robot_id: LeRobot calibration id (``<id>.json``).
        calibration_dir: LeRobot calibration folder.
        calibration_file: A calibration file: LeRobot's JSON for an arm; any joint-map format robocal reads for
            a source.
        source: A ``--source`` (``can:…``, ``sim:lite``, ``replay:…``), with ``urdf`` and ``calibration_file``.
        urdf: The URDF (joint stops) for ``source``.
        margin_deg: How far past a stop a reading may go, degrees.
        max_speed_deg_s: Speed limit of every joint, °/s.
        max_accel_deg_s2: Acceleration limit of every joint's reading, °/s².
        seconds: Stop after this long (the samples' clock); None: until interrupted or the source ends.
        rate_hz: Readings per second at most (an arm's bus).
        leader_port: The leader arm's port (teleoperation): its readings are watched too (joints named
            ``leader <motor>``) and each follower joint it shares but the gripper is checked for being pinned.
        leader_robot: The leader's robot profile.
        leader_id: The leader's calibration id (in ``calibration_dir``).
        leader_file: The leader's calibration JSON (instead of ``leader_id``).
    """

    lerobot_port: str | None = None
    robot: str | None = None
    robot_id: str | None = None
    calibration_dir: Path | None = None
    calibration_file: Path | None = None
    source: str | None = None
    urdf: Path | None = None
    margin_deg: float = 2.0
    max_speed_deg_s: float = 360.0
    max_accel_deg_s2: float = math.degrees(50.0)
    seconds: float | None = None
    rate_hz: float = 60.0
    leader_port: str | None = None
    leader_robot: str | None = None
    leader_id: str | None = None
    leader_file: Path | None = None

    def __post_init__(self) -> None:
        if self.leader_port is not None and (self.lerobot_port is None or self.leader_robot is None):
            raise UsageError(
                "--leader-port goes with --lerobot-port and needs --leader-robot (so101_leader, ...)"
            )
        if self.leader_port is None and (self.leader_robot, self.leader_id, self.leader_file) != (
            None,
            None,
            None,
        ):
            raise UsageError("--leader-robot, --leader-id and --leader-file go with --leader-port")
        if (self.lerobot_port is None) == (self.source is None):
            raise UsageError("give --lerobot-port PORT --robot ROBOT, or --source SOURCE (one of the two)")
        if self.lerobot_port is not None and self.robot is None:
            raise UsageError("--lerobot-port needs --robot (so101_follower, koch_leader, ...)")
        if self.source is not None:
            if self.urdf is None or self.calibration_file is None:
                raise UsageError(
                    "--source needs --urdf (the joints' stops) and --calibration (the joint map)"
                )
            if self.robot_id is not None or self.calibration_dir is not None:
                raise UsageError("--id and --calibration-dir are for --lerobot-port; give --calibration")
        for name in ("margin_deg", "max_speed_deg_s", "max_accel_deg_s2", "rate_hz"):
            v = getattr(self, name)
            if not (math.isfinite(v) and (v >= 0 if name == "margin_deg" else v > 0)):
                raise UsageError(f"--{name.replace('_', '-')}: expected a positive number, got {v!r}")
        if self.rate_hz < _MIN_RATE_HZ:  # the pause between readings must be one time.sleep can take
            raise UsageError(
                f"--rate-hz: expected at least {_MIN_RATE_HZ:g} (one reading in 1000 s), got {self.rate_hz!r}"
            )
        if self.seconds is not None and not (math.isfinite(self.seconds) and self.seconds > 0):
            raise UsageError(f"--seconds: expected a positive number, got {self.seconds!r}")


@dataclass(frozen=True)
class WatchResult:
    """What a watch saw.

    Attributes:
        joint_names: The joints watched.
        ticks: Readings checked.
        seconds: Time covered by the readings, s.
        flags: Every flag raised, in order.
    """

    joint_names: tuple[str, ...]
    ticks: int
    seconds: float
    flags: tuple[HealthFlag, ...]


@dataclass(frozen=True)
class _Stream:
    """An open reader: joint names, stops (rad), wrapping joints, and the readings ``(t_s, q_rad)``."""

    names: tuple[str, ...]
    lower_rad: tuple[float, ...]
    upper_rad: tuple[float, ...]
    wraps: tuple[bool, ...]
    readings: Iterator[tuple[float, FloatArray, FloatArray | None]]
    where: str
    paired: tuple[bool, ...] = ()


def _config(req: WatchRequest, s: _Stream) -> MonitorConfig:
    return monitor_config(
        s.names,
        s.lower_rad,
        s.upper_rad,
        math.radians(req.max_speed_deg_s),
        max_accel_rad_s2=math.radians(req.max_accel_deg_s2),
        wraps=list(s.wraps),
        leader_paired=list(s.paired) or False,
        margin_rad=math.radians(req.margin_deg),
    )


def watch(
    request: WatchRequest,
    on_flag: Callable[[HealthFlag], None],
    *,
    on_start: Callable[[tuple[str, ...], str], None] | None = None,
    on_tick: Callable[[int], None] | None = None,
    clock: Callable[[], float] = time.monotonic,
    sleep: Callable[[float], None] = time.sleep,
) -> WatchResult:
    """Watch until ``request.seconds`` pass, the source ends, or the caller interrupts (KeyboardInterrupt).

    Args:
        request: What to watch.
        on_flag: Called with each flag as it is raised (its ``t_s``: seconds since the first reading).
        on_start: Called once the device is open, with the joint names and where they are read.
        on_tick: Called after each tick with its index (a test moves a simulated joint here).
        clock: The arm's clock, s (a test gives a simulated one).
        sleep: How the arm's loop waits for its next reading.

    Returns:
        What was seen. An interrupt (Ctrl-C) propagates after the device is closed; the flags raised until then
        have gone to ``on_flag``.

    Raises:
        UsageError: Bad options, an unknown robot, a calibration missing a motor or joint.
        FileFormatError: An unreadable calibration, URDF or recording.
        DeviceError: The bus fails.
    """
    ticks, t0, t_last = 0, math.nan, math.nan
    if request.lerobot_port is not None:
        opened = _lerobot_stream(request, clock, sleep)
    else:
        opened = _source_stream(request)
    with opened as stream:
        monitor = Monitor(_config(request, stream))
        if on_start is not None:
            on_start(stream.names, stream.where)
        for t_s, q, q_leader in stream.readings:
            if math.isnan(t0):
                t0 = t_s
            if request.seconds is not None and t_s - t0 > request.seconds:
                break
            if t_s <= t_last:
                continue  # a repeated time stamp (a recording's duplicate row): nothing new
            t_last = t_s
            # flags carry seconds since the first reading; a follower is commanded to its leader's number
            for flag in monitor.update(t_s - t0, q, q_leader, q_leader):
                on_flag(flag)
            ticks += 1
            if on_tick is not None:
                on_tick(ticks)
    span = 0.0 if math.isnan(t0) else t_last - t0
    return WatchResult(stream.names, ticks, span, tuple(monitor.history))


@contextlib.contextmanager
def _lerobot_stream(
    req: WatchRequest, clock: Callable[[], float], sleep: Callable[[float], None]
) -> Iterator[_Stream]:
    """A LeRobot arm (and its leader, when given) read by SYNC_READ, as radians about the recorded ranges."""
    from .arm_reader import open_reader

    assert req.lerobot_port is not None and req.robot is not None
    with contextlib.ExitStack() as stack:
        arm = stack.enter_context(
            open_reader(req.robot, req.lerobot_port, req.robot_id, req.calibration_dir, req.calibration_file)
        )
        lead = None
        if req.leader_port is not None and req.leader_robot is not None:
            lead = stack.enter_context(
                open_reader(
                    req.leader_robot,
                    req.leader_port,
                    req.leader_id,
                    req.calibration_dir,
                    req.leader_file,
                    "--leader-port",
                )
            )
        names, lower, upper = list(arm.names), list(arm.lower_rad), list(arm.upper_rad)
        pairs: list[int] = []  # per follower joint: its leader joint's index, or -1
        if lead is not None:
            pairs = [lead.names.index(n) if n in lead.names and n != "gripper" else -1 for n in arm.names]
            names += [f"leader {n}" for n in lead.names]
            lower += list(lead.lower_rad)
            upper += list(lead.upper_rad)
        n_arm = len(arm.names)
        period = 1.0 / req.rate_hz

        def readings() -> Iterator[tuple[float, FloatArray, FloatArray | None]]:
            lead_q = np.full(len(names), np.nan)
            take = np.array([k for k in pairs if k >= 0], dtype=np.int64)
            put = np.array([i for i, k in enumerate(pairs) if k >= 0], dtype=np.int64)
            next_t = clock()
            # --seconds ends the watch at the first reading past it: a long period's pause stops there
            deadline = math.inf if req.seconds is None else next_t + req.seconds + 1e-3
            while True:
                q = arm.read()
                t = clock()
                if lead is None:
                    yield t, q, None
                else:
                    ql = lead.read()
                    lead_q[put] = ql[take]
                    yield t, np.concatenate([q, ql]), lead_q
                next_t += period
                pause = min(next_t, deadline) - clock()
                if pause > 0:
                    sleep(pause)
                else:
                    next_t = clock()

        where = f"{req.robot} on {req.lerobot_port}"
        if lead is not None:
            where += f" with its leader {req.leader_robot} on {req.leader_port}"
        paired = tuple(i < n_arm and pairs[i] >= 0 for i in range(len(names))) if lead is not None else ()
        yield _Stream(
            tuple(names), tuple(lower), tuple(upper), (False,) * len(names), readings(), where, paired
        )


@contextlib.contextmanager
def _source_stream(req: WatchRequest) -> Iterator[_Stream]:
    """A ``--source`` mapped into the joint frame by the calibration file.

    No 2π branch selection: a reading on the wrong branch is what the monitor flags.
    """
    from ...backends.sources import open_source
    from ..sweep.joint_specs import joint_calibration, read_joints
    from ..sweep.session import check_source_options

    assert req.source is not None and req.urdf is not None and req.calibration_file is not None
    spec = check_source_options(req.source)
    all_joints, cf = read_joints(req.urdf, req.calibration_file, req.robot)
    keep = [i for i, j in enumerate(all_joints) if j.name in cf.calibration]
    if not keep:
        raise UsageError(f"calibration {req.calibration_file}: no offset for any joint of the URDF")
    joints = [all_joints[i] for i in keep]
    cal = joint_calibration(cf, joints)
    d = np.array([j.direction for j in joints], dtype=np.float64)
    src = open_source(spec, all_joints)
    try:
        wraps = src.frame == "motor"  # raw multi-turn motor positions (Robstride): a whole turn can be off

        def readings() -> Iterator[tuple[float, FloatArray, FloatArray | None]]:
            src.begin_sweep()
            while True:
                sample = src.read()
                if sample is None:
                    if src.exhausted:
                        return
                    continue
                pos = sample.position_rad[keep]
                raw = pos if src.frame == "motor" else d * pos
                yield sample.t_s, cal.to_joint(raw), None

        if not joints:
            raise FileFormatError(f"source {req.source}: no joints")
        yield _Stream(
            tuple(j.name for j in joints),
            tuple(j.lower for j in joints),
            tuple(j.upper for j in joints),
            (wraps,) * len(joints),
            readings(),
            req.source,
        )
    finally:
        src.close()
