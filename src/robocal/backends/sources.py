"""Joint-position sources for the sweep: a simulated Lite, live Robstride CAN buses, or a recording.

Source strings (``--source``):

* ``sim:lite`` or ``sim:lite?seed=N&noise=R&skip=a,b&short=joint:R&flip=a&zero_sta=1&single_turn=1`` — the
  simulated Lite bimanual robot with its simulated operator (see :mod:`robocal.backends.sim.lite`).
* ``can:<interface>:<channel>[,<channel>…]`` — live Robstride motors, e.g. ``can:socketcan:can0,can1``; each
  joint is found on the channel where its CAN id answers.
* ``replay:<file>`` — a CSV (``t,<joint>,…``) or a rosbag2 folder/file (sqlite3 or mcap) of
  ``sensor_msgs/msg/JointState``.

A source yields :class:`Sample` rows in its :attr:`frame`: ``"motor"`` (raw motor positions, what the buses
read) or ``"identity"`` (``direction·raw``, what a robot publishes with an empty calibration file).
"""

from __future__ import annotations

import math
import time
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Protocol
from urllib.parse import parse_qs

import numpy as np
import numpy.typing as npt

from ..errors import CalibTimeoutError, JointMismatchError, UsageError

__all__ = [
    "FRAMES",
    "JointSpec",
    "ReplaySource",
    "RobstrideSource",
    "Sample",
    "SimLiteSource",
    "Source",
    "SourceSpec",
    "StreamReplaySource",
    "open_source",
    "parse_source",
]

FRAMES = ("identity", "motor")
FloatArray = npt.NDArray[np.float64]


@dataclass(frozen=True)
class JointSpec:
    """What a source needs to know about a joint (from the URDF).

    Attributes:
        name: Joint name.
        can_id: Motor CAN id (0 when unknown, e.g. for a recording).
        model: Robstride model name.
        direction: URDF ``direction`` (±1).
        lower: Lower limit, rad.
        upper: Upper limit, rad.
    """

    name: str
    can_id: int = 0
    model: str = "rs-00"
    direction: int = 1
    lower: float = -math.pi
    upper: float = math.pi


@dataclass(frozen=True)
class Sample:
    """One reading of every joint.

    Attributes:
        t_s: Time stamp, s.
        position_rad: Shape ``(N,)``, in the source's frame (NaN: joint not in this sample).
        velocity_rad_s: Shape ``(N,)`` or None, same frame.
        effort_nm: Shape ``(N,)`` or None, same frame.
    """

    t_s: float
    position_rad: FloatArray
    velocity_rad_s: FloatArray | None = None
    effort_nm: FloatArray | None = None


@dataclass(frozen=True)
class SourceSpec:
    """A parsed ``--source`` string.

    Attributes:
        kind: ``"sim"``, ``"can"`` or ``"replay"``.
        robot: Simulated robot name (``"lite"``).
        options: ``sim:`` query options.
        interface: python-can interface for ``can:``.
        channels: CAN channels for ``can:``.
        path: Recording for ``replay:``.
        text: The original string.
    """

    kind: str
    robot: str = ""
    options: Mapping[str, str] = field(default_factory=dict)
    interface: str = ""
    channels: tuple[str, ...] = ()
    path: str = ""
    text: str = ""


SIM_OPTIONS = ("seed", "noise", "skip", "short", "flip", "zero_sta", "single_turn")


def parse_source(text: str) -> SourceSpec:
    """Parse a ``--source`` string.

    Raises:
        UsageError: The string is malformed; the message shows the accepted forms.
    """
    forms = "expected sim:lite[?seed=N], can:<interface>:<channel>[,<channel>...] or replay:<file>"
    kind, sep, rest = text.partition(":")
    if not sep or not rest:
        raise UsageError(f"--source {text!r}: {forms}")
    if kind == "sim":
        robot, _, query = rest.partition("?")
        if robot != "lite":
            raise UsageError(f"--source {text!r}: unknown simulated robot {robot!r}; expected sim:lite")
        opts: dict[str, str] = {}
        if query:
            try:
                parsed = parse_qs(query, keep_blank_values=True, strict_parsing=True)
            except ValueError:
                raise UsageError(
                    f"--source {text!r}: malformed options {query!r}; expected key=value&..."
                ) from None
            for key, values in parsed.items():
                if key not in SIM_OPTIONS:
                    raise UsageError(
                        f"--source {text!r}: unknown option {key!r}; valid: {', '.join(SIM_OPTIONS)}"
                    )
                if key in ("skip", "short", "flip"):
                    opts[key] = ",".join(values)  # skip=a&skip=b means skip=a,b
                elif len(values) > 1:
                    raise UsageError(f"--source {text!r}: option {key!r} is given {len(values)} times")
                else:
                    opts[key] = values[0]
        if "seed" in opts and not (opts["seed"].isascii() and opts["seed"].isdigit()):
            raise UsageError(f"--source {text!r}: seed must be a non-negative integer, got {opts['seed']!r}")
        for key in ("zero_sta", "single_turn"):
            if key in opts and opts[key] not in ("0", "1"):
                raise UsageError(f"--source {text!r}: {key} must be 0 or 1, got {opts[key]!r}")
        if "noise" in opts:
            try:
                noise = float(opts["noise"])
            except ValueError:
                noise = math.nan
            if not (math.isfinite(noise) and noise >= 0):
                raise UsageError(f"--source {text!r}: noise must be a number >= 0 rad, got {opts['noise']!r}")
        return SourceSpec("sim", robot=robot, options=opts, text=text)
    if kind == "can":
        interface, sep2, chans = rest.partition(":")
        channels = tuple(c.strip() for c in chans.split(",")) if sep2 else ()
        if not interface or not channels or any(not c for c in channels):
            raise UsageError(f"--source {text!r}: expected can:<interface>:<channel>[,<channel>...]")
        if len(set(channels)) != len(channels):
            raise UsageError(f"--source {text!r}: a CAN channel is listed twice")
        return SourceSpec("can", interface=interface, channels=channels, text=text)
    if kind == "replay":
        return SourceSpec("replay", path=rest, text=text)
    raise UsageError(f"--source {text!r}: unknown kind {kind!r}; {forms}")


class Source(Protocol):
    """What the sweep reads from."""

    joint_names: tuple[str, ...]
    frame: str

    @property
    def exhausted(self) -> bool:
        """True when no more samples will come (end of a recording or of the simulated operator's script)."""
        ...

    def read(self) -> Sample | None:
        """The next sample, or None when exhausted."""
        ...

    def zero_sta(self) -> dict[str, int]:
        """Power-on range per joint (``zero_sta``) where the source can tell; empty otherwise."""
        ...

    def begin_sweep(self) -> None:
        """The sweep starts now (the simulated operator starts moving)."""
        ...

    def prompt_positive(self, joint: str) -> None:
        """The guided direction check asks the operator to move ``joint`` toward its + limit."""
        ...

    def close(self) -> None:
        """Release buses and files."""
        ...


class RobstrideSource:
    """Live joint positions from Robstride buses, read passively (MIT zero-torque polls).

    Args:
        joints: The joints (with CAN id and model).
        buses: One :class:`~robocal.backends.robstride.RobstrideBus` per channel, each listing its joints.
    """

    frame = "motor"

    def __init__(self, joints: Sequence[JointSpec], buses: Sequence[Any]) -> None:
        self.joints = tuple(joints)
        self.joint_names = tuple(j.name for j in self.joints)
        self.buses = list(buses)
        self._index = {n: i for i, n in enumerate(self.joint_names)}
        self._t0 = time.monotonic()

    @property
    def exhausted(self) -> bool:
        """A live robot never runs out."""
        return False

    def read(self) -> Sample:
        """Poll every joint once (zero torque) and return raw positions, velocities and torques."""
        n = len(self.joint_names)
        pos = np.full(n, np.nan)
        vel = np.full(n, np.nan)
        eff = np.full(n, np.nan)
        for bus in self.buses:
            for name, fb in bus.zero_torque().items():
                i = self._index[name]
                pos[i], vel[i], eff[i] = fb.position_rad, fb.velocity_rad_s, fb.torque_nm
        return Sample(self._now(), pos, vel, eff)

    def _now(self) -> float:
        return time.monotonic() - self._t0

    def zero_sta(self) -> dict[str, int]:
        """Read ``zero_sta`` (0x7029) of every motor."""
        from .robstride.protocol import Param

        out: dict[str, int] = {}
        for bus in self.buses:
            out.update({k: int(v) for k, v in bus.read_param_many(list(bus.motors), Param.ZERO_STA).items()})
        return out

    def begin_sweep(self) -> None:
        """Nothing to do on a live robot (the operator is a person)."""

    def prompt_positive(self, joint: str) -> None:
        """Nothing to do on a live robot (the CLI shows the instruction)."""

    def close(self) -> None:
        """Close every bus."""
        for bus in self.buses:
            bus.close()
        self.buses = []


class SimLiteSource(RobstrideSource):
    """The simulated Lite robot read through the real :class:`RobstrideBus` code path.

    Each :meth:`read` first advances simulated time by one tick (the simulated operator moves), then polls the
    motors over the ``virtual`` bus. The source is exhausted a few ticks after the operator's sweep ends.
    """

    def __init__(self, joints: Sequence[JointSpec], sim: Any, *, timeout_s: float = 5.0) -> None:
        # the simulated motors answer at once; a long reply timeout only matters on a heavily loaded machine,
        # where a thread may wait for the GIL longer than a real bus's 0.5 s
        from .robstride import MotorSpec, RobstrideBus
        from .sim.lite import LITE_JOINTS

        table = {j.name: j for j in LITE_JOINTS}
        unknown = [j.name for j in joints if j.name not in table]
        if unknown:
            raise JointMismatchError(
                f"sim:lite has no joint(s) {', '.join(unknown)}; it simulates {', '.join(table)}"
            )
        self.sim = sim
        buses = []
        for bus_name, channel in sim.channels.items():
            specs = [MotorSpec(j.name, table[j.name].can_id, table[j.name].model) for j in joints]
            specs = [s for s in specs if table[s.name].bus == bus_name]
            if specs:
                buses.append(RobstrideBus(channel, specs, interface="virtual", timeout_s=timeout_s))
        super().__init__(joints, buses)
        self._idle = 0

    @property
    def exhausted(self) -> bool:
        """True a few ticks after the simulated operator finished the sweep."""
        return bool(self.sim.operator.sweep_started and self._idle > 3)

    def read(self) -> Sample:
        """Advance the simulation one tick, then poll the motors."""
        self.sim.step()
        if self.sim.operator.sweep_started and not self.sim.operator.busy:
            self._idle += 1
        s = super().read()
        return Sample(self.sim.t_s, s.position_rad, s.velocity_rad_s, s.effort_nm)

    def begin_sweep(self) -> None:
        """The simulated operator starts sweeping."""
        self.sim.operator.begin_sweep()

    def prompt_positive(self, joint: str) -> None:
        """The simulated operator moves ``joint`` toward its + limit."""
        self.sim.operator.move_toward_plus(joint)

    def close(self) -> None:
        """Close the buses and stop the simulated robot."""
        super().close()
        self.sim.stop()


class StreamReplaySource:
    """Samples streamed from a recording (CSV or rosbag2) in blocks: memory does not grow with its length.

    The first block is read when the source is made, so a file that is malformed from its start is refused
    before the sweep begins; an error further on is raised when the reading reaches it (nothing is written).

    Args:
        joint_names: The joints in URDF order.
        recording: The opened :class:`robocal.backends.replay.Recording`.
        frame: ``"identity"`` or ``"motor"``.
    """

    def __init__(self, joint_names: Sequence[str], recording: Any, frame: str) -> None:
        self.joint_names = tuple(joint_names)
        self.frame = frame
        self.recording = recording
        self._t: FloatArray = np.empty(0)
        self._pos: FloatArray = np.empty((0, len(self.joint_names)))
        self._i = 0
        self._done = False
        try:  # the first block now: a malformed start of the file is refused before the sweep begins
            self._fill()
        except BaseException:
            self.close()
            raise

    def _fill(self) -> bool:
        """Make sure rows are buffered; False at the end of the recording."""
        while self._i >= len(self._t):
            if self._done:
                return False
            try:
                self._t, self._pos = next(self.recording)
            except StopIteration:
                self._done = True
                return False
            self._i = 0
        return True

    @property
    def exhausted(self) -> bool:
        """True after the last row (reads ahead one block to know)."""
        return not self._fill()

    @property
    def progress(self) -> tuple[int, int, str, int]:
        """``(done, total, unit, rows)``: bytes (CSV) or messages (bag) read of the total, rows delivered."""
        r = self.recording
        return int(r.done), int(r.total), str(r.unit), int(r.rows)

    def read(self) -> Sample | None:
        """The next row, or None at the end."""
        if not self._fill():
            return None
        i = self._i
        self._i += 1
        return Sample(float(self._t[i]), self._pos[i].copy())

    def read_block(self, max_rows: int = 1 << 30) -> tuple[FloatArray, FloatArray]:
        """Up to ``max_rows`` rows at once (at most one buffered block): ``(t (T,), positions (T, N))``."""
        if not self._fill():
            return self._t[:0], self._pos[:0]
        i = self._i
        j = min(len(self._t), i + max_rows)
        self._i = j
        return self._t[i:j], self._pos[i:j]

    def zero_sta(self) -> dict[str, int]:
        """A recording does not say."""
        return {}

    def begin_sweep(self) -> None:
        """Nothing to do."""

    def prompt_positive(self, joint: str) -> None:
        """A recording cannot answer prompts."""
        raise UsageError("--direction-check needs a live or simulated source, not a replay")

    def close(self) -> None:
        """Release the file."""
        self.recording.close()


class ReplaySource(StreamReplaySource):
    """Samples from a recording already loaded into memory: one block, read as a streamed one.

    Args:
        joint_names: The joints in URDF order.
        t_s: Shape ``(T,)``, s.
        positions_rad: Shape ``(T, N)`` in ``frame`` (NaN where a joint is missing).
        frame: ``"identity"`` or ``"motor"``.
    """

    def __init__(
        self, joint_names: Sequence[str], t_s: FloatArray, positions_rad: FloatArray, frame: str
    ) -> None:
        from .replay import Recording

        self.t_s = t_s
        self.positions_rad = positions_rad
        blocks = iter([(t_s, positions_rad)])
        super().__init__(joint_names, Recording(Path("<memory>"), "memory", 0, "rows", blocks), frame)


def _sim_lite(spec: SourceSpec, joints: Sequence[JointSpec]) -> SimLiteSource:
    from .sim.lite import SimLite

    o = spec.options
    names = {j.name for j in joints}

    def names_of(key: str) -> list[str]:
        items = [x for x in o.get(key, "").split(",") if x]
        bad = [x for x in items if x not in names]
        if bad:
            raise UsageError(f"--source {spec.text!r}: {key}: unknown joint(s) {', '.join(bad)}")
        return items

    short: dict[str, float] = {}
    for item in [x for x in o.get("short", "").split(",") if x]:
        joint, _, amount = item.partition(":")
        try:
            value = float(amount or "0.4")
        except ValueError:
            value = math.nan
        if joint not in names or not (math.isfinite(value) and value >= 0):
            raise UsageError(f"--source {spec.text!r}: short: expected joint[:rad], got {item!r}")
        short[joint] = value
    sim = SimLite(
        int(o.get("seed", "0")),
        noise_rad=float(o.get("noise", "3e-4")),
        flip=names_of("flip"),
        zero_sta=int(o.get("zero_sta", "1")),
        single_turn=o.get("single_turn", "0") == "1",
        skip=names_of("skip"),
        short_rad=short,
    )
    sim.start()
    try:
        return SimLiteSource(joints, sim)
    except BaseException:
        sim.stop()
        raise


def _can(spec: SourceSpec, joints: Sequence[JointSpec], timeout_s: float) -> RobstrideSource:
    from .robstride import MotorSpec, RobstrideBus
    from .robstride.protocol import model_limits

    missing_ids = [j.name for j in joints if j.can_id <= 0]
    if missing_ids:
        raise UsageError(f"joints without a can_id param in the URDF: {', '.join(missing_ids)}")
    for j in joints:
        try:
            model_limits(j.model)
        except UsageError as exc:
            raise UsageError(f"joint {j.name!r}: {exc}") from None
    if len(spec.channels) == 1:
        specs = [MotorSpec(j.name, j.can_id, j.model) for j in joints]
        bus = RobstrideBus(spec.channels[0], specs, interface=spec.interface, timeout_s=timeout_s)
        return RobstrideSource(joints, [bus])
    # several channels: find each joint where its CAN id answers a (harmless) type-0 device-id request
    probes = [RobstrideBus(ch, [], interface=spec.interface, timeout_s=timeout_s) for ch in spec.channels]
    try:
        found = [p.probe([j.can_id for j in joints]) for p in probes]
    finally:
        for p in probes:
            p.close()
    buses = []
    placed: set[str] = set()
    for ch, ids in zip(spec.channels, found, strict=True):
        specs = [
            MotorSpec(j.name, j.can_id, j.model) for j in joints if j.can_id in ids and j.name not in placed
        ]
        placed.update(s.name for s in specs)
        if specs:
            buses.append(RobstrideBus(ch, specs, interface=spec.interface, timeout_s=timeout_s))
    lost = [f"{j.name!r} (CAN id {j.can_id})" for j in joints if j.name not in placed]
    if lost:
        for b in buses:
            b.close()
        raise CalibTimeoutError(f"no reply on {', '.join(spec.channels)} from {', '.join(lost)}")
    return RobstrideSource(joints, buses)


def open_source(
    spec: SourceSpec | str,
    joints: Sequence[JointSpec],
    *,
    topic: str = "/lite/joint_states",
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
    if frame is not None and frame not in FRAMES:
        raise UsageError(f"--frame {frame!r}: expected one of {', '.join(FRAMES)}")
    if spec.kind == "sim":
        return _sim_lite(spec, joints)
    if spec.kind == "can":
        return _can(spec, joints, timeout_s)
    from .replay import open_recording

    names = [j.name for j in joints]
    recording = open_recording(Path(spec.path), names, topic=topic)
    return StreamReplaySource(names, recording, frame or "identity")
