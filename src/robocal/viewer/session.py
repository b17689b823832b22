"""``robocal view`` as a function: URDF + source + calibrations → a started page and feed.

:func:`open_view` validates everything (URDF, calibration files, source string, port) before it serves
anything, so bad input gives one :class:`~robocal.errors.CalibError` and nothing runs. It never writes a file.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from ..backends.sources import DEFAULT_TOPIC, JointSpec, parse_source
from ..core.arrays import FloatArray
from ..core.jointmap import RobotCalibration
from ..core.lifecycle import ClosesOnExit
from ..errors import FileFormatError, JointMismatchError, UsageError
from .access import parse_allowed_origins
from .app import ViewerApp
from .feeds import Feed, PollFeed, ReplayFeed, SourceFeed, reorder
from .mapping import JointMapper
from .model import RobotModel, load_robot_model, parse_package_paths

__all__ = ["COMPARE_IDENTITY", "ViewOptions", "ViewSession", "open_view"]

COMPARE_IDENTITY = ("none", "identity")
"""``--compare`` values meaning "no calibration" (``direction·raw``)."""
MAX_REPLAY_ROWS = 5_000_000
"""Rows of a recording the replay slider holds in memory."""


@dataclass
class ViewOptions:
    """Everything ``robocal view`` takes.

    Attributes:
        urdf: The robot description.
        source: ``sim:lite…``, ``can:…`` or ``replay:FILE`` (see :mod:`robocal.backends.sources`).
        lerobot_port: Serial port of a LeRobot arm (or ``sim``), instead of ``source``.
        robot: LeRobot robot type with ``lerobot_port`` (``so101_follower`` …).
        robot_id: LeRobot robot id (its calibration file) with ``lerobot_port``.
        calibration_dir: LeRobot calibration root.
        ur_host: UR controller address, instead of ``source``.
        calibration: Calibration file of the robot (any robocal format; a LeRobot JSON with ``lerobot_port``).
        compare: Second calibration drawn as a ghost, or ``none``/``identity``.
        package_paths: ``NAME=DIR`` for ``package://`` meshes.
        frame: Frame of a replay (``identity`` default, or ``motor``).
        topic: JointState topic of a rosbag2 replay.
        profile: Robot profile (name or file) for directions and ids the URDF lacks.
        host: Interface to serve on.
        port: TCP port (0: any free).
        rate_hz: Page updates per second.
        speed: Replay speed.
        keep_moving: With ``sim:lite``, the simulated operator sweeps again and again.
        allowed_origins: ``--allow-origin`` values: other origins the page may be used from (``*``: any).
    """

    urdf: Path
    source: str | None = None
    lerobot_port: str | None = None
    robot: str | None = None
    robot_id: str | None = None
    calibration_dir: Path | None = None
    ur_host: str | None = None
    calibration: Path | None = None
    compare: str | None = None
    package_paths: Sequence[str] = field(default_factory=tuple)
    frame: str | None = None
    topic: str = DEFAULT_TOPIC
    profile: str | None = None
    host: str = "127.0.0.1"
    port: int = 8080
    rate_hz: float = 30.0
    speed: float = 1.0
    keep_moving: bool = False
    allowed_origins: Sequence[str] = field(default_factory=tuple)


@dataclass
class ViewSession(ClosesOnExit):
    """A running view: the page and the feed (stop both with :meth:`close`).

    Attributes:
        app: The page.
        feed: The source's thread.
        warnings: Load-time warnings (missing meshes, joints without a calibration), already on the page.
    """

    app: ViewerApp
    feed: Feed
    warnings: list[str]

    def close(self) -> None:
        """Stop the feed (releasing buses/files), then the server."""
        try:
            self.feed.stop()
        finally:
            self.app.stop()


def _joints(model: RobotModel, urdf_path: Path, profile_name: str | None, cf: Any) -> list[JointSpec]:
    """The shown joints as source joint specs: direction, CAN id, model from the URDF/profile/file."""
    from ..formats.profiles import resolve_profile
    from ..formats.urdf import read_urdf
    from ..workflows.sweep.joint_specs import joints_from_urdf

    urdf = read_urdf(urdf_path)
    profile = resolve_profile(profile_name, urdf)
    try:
        specs = {j.name: j for j in joints_from_urdf(urdf, profile, cf)}
    except FileFormatError:  # some joint lacks a direction: assume +1 for those (a viewer need not refuse)
        specs = {}
    out = []
    for i, name in enumerate(model.actuated):
        j = specs.get(name)
        if j is None:
            d = urdf.direction(name) if urdf.has_joint(name) else None
            j = JointSpec(name, direction=d or 1, lower=float(model.lower[i]), upper=float(model.upper[i]))
        out.append(j)
    return out


def _directions(joints: Sequence[JointSpec]) -> dict[str, int]:
    return {j.name: int(j.direction) for j in joints}


def _read_cal(path: Path, urdf_path: Path, profile: str | None) -> Any:
    from ..formats import read_calibration
    from ..formats.profiles import resolve_profile
    from ..formats.urdf import read_urdf

    urdf = read_urdf(urdf_path)
    return read_calibration(path, urdf=urdf, robot=resolve_profile(profile, urdf))


def _mapper(
    cf: Any, names: Sequence[str], directions: dict[str, int], label: str, warnings: list[str]
) -> JointMapper:
    if cf is None:
        cal = RobotCalibration.identity(names, [directions[n] for n in names])
        return JointMapper(names, cal, label)
    cal = cf.calibration
    common = [n for n in names if n in cal]
    if not common:
        raise JointMismatchError(
            f"{label}: none of its joints ({', '.join(cal.joint_names[:6])}…) is a joint of the URDF "
            f"({', '.join(names[:6])}…)"
        )
    lacking = [n for n in names if n not in cal]
    full = cal.select(common)
    if lacking:
        warnings.append(f"{label} has no entry for {', '.join(lacking)}: shown as direction·raw")
        extra = RobotCalibration.identity(lacking, [directions[n] for n in lacking])
        full = RobotCalibration(
            [*common, *lacking],
            np.concatenate([full.direction, extra.direction]),
            np.concatenate([full.homing_offset, extra.homing_offset]),
            np.concatenate([full.scale, extra.scale]),
        )
    return JointMapper(names, full, label)


def _check_exclusive(opts: ViewOptions) -> str:
    given = [
        flag
        for flag, value in (
            ("--source", opts.source),
            ("--lerobot-port", opts.lerobot_port),
            ("--ur-host", opts.ur_host),
        )
        if value
    ]
    if len(given) != 1:
        raise UsageError(
            "give exactly one of --source, --lerobot-port or --ur-host"
            + (f" (got {', '.join(given)})" if given else "")
        )
    if opts.lerobot_port and not opts.robot:
        raise UsageError(
            "--lerobot-port needs --robot (so101_follower, so101_leader, koch_follower, koch_leader)"
        )
    if not opts.lerobot_port and (opts.robot_id or opts.calibration_dir):
        raise UsageError("--id and --calibration-dir go with --lerobot-port")
    return given[0]


def open_view(opts: ViewOptions) -> ViewSession:
    """Validate the options, start the page, then the feed.

    Raises:
        CalibError: Any bad input (URDF, calibration, source string, port), before anything is served.
    """
    kind = _check_exclusive(opts)
    parse_allowed_origins(opts.allowed_origins)
    packages = parse_package_paths(list(opts.package_paths))
    spec = parse_source(opts.source) if opts.source else None
    if opts.frame is not None and (spec is None or spec.kind != "replay"):
        raise UsageError("--frame goes with --source replay:FILE")
    model = load_robot_model(opts.urdf, packages)
    warnings = list(model.warnings)
    names = model.actuated
    if kind == "--lerobot-port":
        return _open_lerobot(opts, model, warnings)
    if kind == "--ur-host":
        return _open_ur(opts, model, warnings)
    assert spec is not None
    cf = _read_cal(opts.calibration, opts.urdf, opts.profile) if opts.calibration else None
    joints = _joints(model, opts.urdf, opts.profile, cf)
    dirs = _directions(joints)
    cal = _mapper(
        cf, names, dirs, opts.calibration.name if opts.calibration else "none (direction·raw)", warnings
    )
    compare = None
    if opts.compare is not None:
        if opts.compare.strip().lower() in COMPARE_IDENTITY:
            compare = _mapper(None, names, dirs, "none (direction·raw)", warnings)
        else:
            path = Path(opts.compare)
            compare = _mapper(_read_cal(path, opts.urdf, opts.profile), names, dirs, path.name, warnings)
    app = _app(opts, model, spec.text, calibration=cal, compare=compare)
    if spec.kind == "replay":
        feed: Feed = _replay_feed(app, spec.path, opts, joints)
    else:
        feed = _live_feed(app, spec, joints, opts.keep_moving)
    return _start(app, feed, warnings)


def _app(opts: ViewOptions, model: RobotModel, what: str, **mapping: Any) -> ViewerApp:
    """The page of ``model`` titled ``model — what``, served on the options' host, port and rate.

    ``mapping`` holds the page's ``calibration``, ``compare`` and ``raw_unit`` arguments.
    """
    return ViewerApp(
        model,
        host=opts.host,
        port=opts.port,
        rate_hz=opts.rate_hz,
        title=f"{model.name} — {what}",
        allowed_origins=opts.allowed_origins,
        **mapping,
    )


def _start(app: ViewerApp, feed: Feed, warnings: list[str]) -> ViewSession:
    try:
        if isinstance(feed, ReplayFeed):
            app.attach_replay(feed)
        app.start()
    except BaseException:
        feed.close()
        raise
    for w in warnings:
        app.message(w, "warning")
    feed.start()
    return ViewSession(app, feed, warnings)


def _replay_feed(
    app: ViewerApp, path_text: str, opts: ViewOptions, joints: Sequence[JointSpec]
) -> ReplayFeed:
    from ..backends.replay import read_recording

    path = Path(path_text)
    names = [j.name for j in joints]
    t, pos = read_recording(path, names, topic=opts.topic)
    if len(t) > MAX_REPLAY_ROWS:
        raise UsageError(f"recording {path}: {len(t)} rows; the viewer holds at most {MAX_REPLAY_ROWS}")
    if len(t) == 0:
        raise FileFormatError(f"recording {path}: no samples")
    order = np.argsort(t, kind="stable")
    t, pos = t[order], pos[order]
    frame = opts.frame or "identity"
    if frame not in ("identity", "motor"):
        raise UsageError(f"--frame {frame!r}: expected identity or motor")
    if frame == "identity":  # direction·raw → raw (the map is its own inverse)
        pos = pos * np.array([j.direction for j in joints], dtype=np.float64)
    return ReplayFeed(app, t, pos, path.name, speed=opts.speed)


def _live_feed(app: ViewerApp, spec: Any, joints: Sequence[JointSpec], keep_moving: bool) -> SourceFeed:
    from ..backends.sources import open_source

    source: Any = open_source(spec, joints)
    idx = reorder(source.joint_names, [j.name for j in joints])
    dirs = np.array([j.direction for j in joints], dtype=np.float64)
    identity = source.frame == "identity"

    def to_raw(positions: FloatArray) -> FloatArray:
        out = np.where(idx >= 0, positions[np.maximum(idx, 0)], math.nan)
        return out * dirs if identity else out

    again = None
    if spec.kind == "sim":
        source.begin_sweep()
        if keep_moving:

            def again() -> bool:
                source._idle = 0  # the simulated operator sweeps again
                source.begin_sweep()
                return True

    return SourceFeed(app, source, spec.text, to_raw, paced=spec.kind == "sim", keep_moving=again)


def _lerobot_maps(spec: Any, cals: Any, names: Sequence[str]) -> tuple[list[str], RobotCalibration]:
    """Motor → URDF joint names and a ticks → rad map for every motor (range-mode motors about their mid)."""
    from ..workflows.lerobot import export_joint_map

    motors = list(spec.motor_names)
    if all(m in names for m in motors):
        joint_of = motors
    elif len(names) >= len(motors):
        joint_of = list(names[: len(motors)])  # e.g. Koch: joint1..joint5, joint_gripper in motor order
    else:
        raise JointMismatchError(
            f"the URDF has {len(names)} movable joints; {spec.name} has {len(motors)} motors ({', '.join(motors)})"
        )
    degrees, _skipped = export_joint_map(spec, cals)
    dirs: list[float] = []
    homes: list[float] = []
    scales: list[float] = []
    for m in motors:
        if m in degrees:
            jm = degrees.joint_map(m)
            dirs.append(jm.direction)
            homes.append(jm.homing_offset)
            scales.append(jm.scale)
        else:  # RANGE_0_100 / RANGE_M100_100 motors: the tick angle about the middle of the range
            c = cals[m]
            dirs.append(1.0)
            homes.append((c.range_min + c.range_max) / 2)
            scales.append(2 * math.pi / 4096)
    return joint_of, RobotCalibration(joint_of, dirs, homes, scales)


def _open_lerobot(opts: ViewOptions, model: RobotModel, warnings: list[str]) -> ViewSession:
    from ..formats.lerobot import calibration_path
    from ..formats.lerobot import read_current as read_calibration
    from ..workflows.lerobot import open_bus, robot_spec

    assert opts.lerobot_port is not None and opts.robot is not None
    spec = robot_spec(opts.robot)
    if opts.calibration is not None:
        cal_path = opts.calibration
    elif opts.robot_id is not None:
        cal_path = calibration_path(spec.kind, spec.device_name, opts.robot_id, root=opts.calibration_dir)
    else:
        raise UsageError("--lerobot-port needs --id (its calibration file) or --calibration FILE")
    cals = read_calibration(cal_path)
    missing = [m for m in spec.motor_names if m not in cals]
    if missing:
        raise JointMismatchError(f"calibration {cal_path}: no entry for motor(s) {', '.join(missing)}")
    names = model.actuated
    joint_of, cal = _lerobot_maps(spec, cals, names)
    mapper = JointMapper(names, cal, cal_path.name)
    compare = None
    if opts.compare is not None:
        if opts.compare.strip().lower() in COMPARE_IDENTITY:
            ident = RobotCalibration(joint_of, 1.0, 2048.0, 2 * math.pi / 4096)
            compare = JointMapper(names, ident, "none (ticks about 2048)")
        else:
            cmp_path = Path(opts.compare)
            compare = JointMapper(
                names, _lerobot_maps(spec, read_calibration(cmp_path), names)[1], cmp_path.name
            )
    app = _app(
        opts, model, f"{spec.name} on {opts.lerobot_port}", calibration=mapper, compare=compare, raw_unit="ticks"
    )
    arm: Any = None
    port = opts.lerobot_port
    if port == "sim":
        from ..backends.sim.lerobot_arms import SimArm
        from ..workflows.lerobot.arms import check_simulated

        check_simulated(spec, port, "--lerobot-port")
        arm = SimArm(spec).start()
        port = arm.port
    try:
        bus = open_bus(spec, port, label=opts.lerobot_port)  # a simulated arm's pty named as given: sim
    except BaseException:
        if arm is not None:
            arm.stop()
        raise
    ids = [m.motor_id for m in spec.motors]
    slot = {j: k for k, j in enumerate(names)}
    where = np.array([slot[j] for j in joint_of], dtype=np.intp)
    n = len(names)

    def poll() -> FloatArray:
        ticks = bus.sync_read("Present_Position", ids)
        out = np.full(n, math.nan)
        out[where] = [float(ticks[i]) for i in ids]
        return out

    def close() -> None:
        try:
            bus.close()
        finally:
            if arm is not None:
                arm.stop()

    feed = PollFeed(app, poll, f"{spec.name}@{opts.lerobot_port}", max_rate_hz=100.0, on_close=close)
    return _start(app, feed, warnings)


def _open_ur(opts: ViewOptions, model: RobotModel, warnings: list[str]) -> ViewSession:
    from ..backends import load_backend

    assert opts.ur_host is not None
    host, _, port_text = opts.ur_host.partition(":")
    try:
        port = int(port_text) if port_text else 30001
    except ValueError:
        raise UsageError(f"--ur-host {opts.ur_host!r}: expected HOST or HOST:PORT") from None
    if opts.calibration is not None or opts.compare is not None:
        raise UsageError(
            "--ur-host shows the controller's joint positions; UR kinematic calibrations are shown by "
            "`robocal ur view`"
        )
    names = model.actuated
    if len(names) < 6:
        raise JointMismatchError(f"URDF {opts.urdf}: {len(names)} movable joints; a UR arm has 6")
    client = load_backend("ur_primary")(host, port)
    client.connect()
    n = len(names)

    def poll() -> FloatArray:
        q = client.read_pose_samples(1)[0].q_rad
        out = np.full(n, math.nan)
        out[:6] = q[:6]
        return out

    app = _app(opts, model, f"UR at {opts.ur_host}")
    feed = PollFeed(app, poll, f"ur@{opts.ur_host}", max_rate_hz=125.0, on_close=client.close)
    return _start(app, feed, warnings)
