"""What a joint-position source is: the ``--source`` string, the joints it reads, its samples, its protocol."""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Protocol
from urllib.parse import parse_qs

from ...core.arrays import FloatArray
from ...errors import UsageError

__all__ = [
    "CAN_OPTIONS",
    "REPLAY_FRAMES",
    "SIM_OPTIONS",
    "SOCKETCAND_DEFAULT_PORT",
    "JointSpec",
    "Sample",
    "Source",
    "SourceSpec",
    "can_bus_options",
    "check_replay_frame",
    "parse_sim_options",
    "parse_source",
]

REPLAY_FRAMES = ("identity", "motor")
"""The frames a source reads in: ``direction·raw`` (a robot publishing with an empty calibration) or raw."""


def check_replay_frame(frame: str | None) -> str | None:
    """``frame`` if it is None or one of :data:`REPLAY_FRAMES`; else the ``--frame`` error that lists them.

    Raises:
        UsageError: Another frame.
    """
    if frame is not None and frame not in REPLAY_FRAMES:
        raise UsageError(f"--frame {frame!r}: expected one of {', '.join(REPLAY_FRAMES)}")
    return frame


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
        options: ``sim:`` query options; ``can:socketcand:`` ``host`` and ``port``.
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
OPENARM_SIM_OPTIONS = ("seed", "zeroed")
"""Options of ``sim:openarm`` for the hand sweep (``sweep --auto`` has its own: autocal/damiao.py)."""
CAN_OPTIONS = ("host", "port")
"""Options of a ``can:socketcand:…?host=H&port=P`` source (the socketcand server; default 127.0.0.1:29536)."""
SOCKETCAND_DEFAULT_PORT = 29536
"""The socketcand daemon's default TCP port."""


def can_bus_options(spec: SourceSpec) -> dict[str, str | int]:
    """The extra ``can.Bus`` keyword arguments of a ``can:`` source (``socketcand``: host and port, defaulted)."""
    if spec.interface != "socketcand":
        return {}
    return {
        "host": spec.options.get("host", "127.0.0.1"),
        "port": int(spec.options.get("port", SOCKETCAND_DEFAULT_PORT)),
    }


def parse_sim_options(
    text: str,
    query: str,
    valid: Sequence[str],
    *,
    joined: Sequence[str] = (),
    valid_label: str = "valid",
) -> dict[str, str]:
    """The ``key=value&...`` options of a ``sim:`` source, checked.

    Args:
        text: The whole ``--source`` text, for messages.
        query: The part after ``?`` (may be empty).
        valid: The option names accepted.
        joined: Options that may repeat; their values are joined with commas (``skip=a&skip=b`` is ``a,b``).
            Any other option given twice is refused.
        valid_label: How the message introduces the valid names.

    Raises:
        UsageError: Malformed text, an unknown or repeated option, a seed that is not a non-negative integer.
    """
    opts: dict[str, str] = {}
    if query:
        try:
            parsed = parse_qs(query, keep_blank_values=True, strict_parsing=True)
        except ValueError:
            raise UsageError(
                f"--source {text!r}: malformed options {query!r}; expected key=value&..."
            ) from None
        for key, values in parsed.items():
            if key not in valid:
                raise UsageError(
                    f"--source {text!r}: unknown option {key!r}; {valid_label}: {', '.join(valid)}"
                )
            if key in joined:
                opts[key] = ",".join(values)
            elif len(values) > 1:
                raise UsageError(f"--source {text!r}: option {key!r} is given {len(values)} times")
            else:
                opts[key] = values[0]
    if "seed" in opts and not (opts["seed"].isascii() and opts["seed"].isdigit()):
        raise UsageError(f"--source {text!r}: seed must be a non-negative integer, got {opts['seed']!r}")
    return opts


def recording_path(text: str | None) -> str | None:
    """The file a ``replay:<file>`` source reads (an input no output may replace), else None."""
    if text is None or not text.startswith("replay:"):
        return None
    return text[len("replay:") :] or None


def parse_source(text: str) -> SourceSpec:
    """Parse a ``--source`` string.

    Raises:
        UsageError: The string is malformed; the message shows the accepted forms.
    """
    forms = (
        "expected sim:lite[?seed=N], can:<interface>:<channel>[,<channel>...][?host=H&port=P] or replay:<file>"
    )
    kind, sep, rest = text.partition(":")
    if not sep or not rest:
        raise UsageError(f"--source {text!r}: {forms}")
    if kind == "sim":
        robot, _, query = rest.partition("?")
        if robot == "openarm":  # the hand sweep of the simulated OpenArm (sources/damiao.py)
            opts = parse_sim_options(text, query, OPENARM_SIM_OPTIONS)
            if opts.get("zeroed", "0") not in ("0", "1"):
                raise UsageError(f"--source {text!r}: zeroed must be 0 or 1, got {opts['zeroed']!r}")
            return SourceSpec("sim", robot=robot, options=opts, text=text)
        if robot != "lite":
            raise UsageError(f"--source {text!r}: unknown simulated robot {robot!r}; expected sim:lite or sim:openarm")
        opts = parse_sim_options(text, query, SIM_OPTIONS, joined=("skip", "short", "flip"))
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
        body, _, query = rest.partition("?")
        interface, sep2, chans = body.partition(":")
        channels = tuple(c.strip() for c in chans.split(",")) if sep2 else ()
        if not interface or not channels or any(not c for c in channels):
            raise UsageError(f"--source {text!r}: expected can:<interface>:<channel>[,<channel>...]")
        if len(set(channels)) != len(channels):
            raise UsageError(f"--source {text!r}: a CAN channel is listed twice")
        opts = parse_sim_options(text, query, CAN_OPTIONS)
        if opts and interface != "socketcand":
            raise UsageError(f"--source {text!r}: host and port apply to can:socketcand only")
        if "port" in opts and not (opts["port"].isascii() and opts["port"].isdigit() and 0 < int(opts["port"]) < 65536):
            raise UsageError(f"--source {text!r}: port must be 1..65535, got {opts['port']!r}")
        if "host" in opts and not opts["host"]:
            raise UsageError(f"--source {text!r}: host is empty")
        return SourceSpec("can", options=opts, interface=interface, channels=channels, text=text)
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
