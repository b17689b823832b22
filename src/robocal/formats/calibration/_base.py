"""What every calibration format module shares: the file value, the format spec and the id/scale rules.

A format module (``lite_json``, ``berkeley``, ...) defines one :class:`FormatSpec` named ``SPEC``: its reader,
its writer (None for a read-only format), the suffixes it is chosen for, and a sniffer that recognises its
content. :mod:`.registry` collects the specs and is the only path for detecting, reading and writing.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from enum import Flag, auto
from pathlib import Path
from typing import Any, Literal, Protocol

from ...core.jointmap import RobotCalibration
from ...core.profile import RobotProfile
from ...errors import FileFormatError, UsageError
from ...fileio import MAX_DOCUMENT_BYTES, read_text
from .._yaml import load_yaml
from ..profiles import joint_motor_id
from ..urdf import UrdfModel

__all__ = ["CalibrationFile", "Content", "FormatSpec", "Reader", "Traits", "Writer"]


@dataclass(frozen=True)
class CalibrationFile:
    """A joint calibration together with what its file said about the joints.

    Attributes:
        calibration: The canonical joint map.
        ids: Motor id per joint where the file (or URDF) gives one.
        fmt: Format name the data was read from (or is meant for).
        source: Path or description of the origin.
        notes: Human-readable remarks made while reading (e.g. values taken from the URDF).
        ranges_rad: Joint → measured (lower, upper) range in the joint frame, rad, where it is known (a sweep's
            stops); formats that store a range (``openarm-lerobot``) write it, the others ignore it.
    """

    calibration: RobotCalibration
    ids: Mapping[str, int] = field(default_factory=dict)
    fmt: str = "robocal"
    source: str = "<memory>"
    notes: tuple[str, ...] = ()
    ranges_rad: Mapping[str, tuple[float, float]] = field(default_factory=dict)


@dataclass(frozen=True)
class Content:
    """A file's content as parsed once for format detection.

    Attributes:
        kind: ``"xml"`` (starts with ``<``; not parsed), ``"json"`` (a JSON object) or ``"yaml"`` (a YAML
            mapping, which includes JSON the strict JSON reader refused but YAML reads).
        data: The parsed mapping (None for ``"xml"``).
        source: The file, for messages.
    """

    kind: Literal["xml", "json", "yaml"]
    data: Any
    source: str


class Reader(Protocol):
    """Reads one format: ``parsed_yaml`` is the document detection already parsed (None: parse the file)."""

    def __call__(
        self,
        path: Path,
        *,
        urdf: UrdfModel | None = None,
        joint_order: Sequence[str] | None = None,
        profile: RobotProfile | None = None,
        parsed_yaml: Any = None,
    ) -> CalibrationFile: ...


class Writer(Protocol):
    """Writes one format atomically (keeping ``NAME.bak``), after validating everything it needs."""

    def __call__(
        self,
        path: Path,
        cf: CalibrationFile,
        urdf: UrdfModel | None,
        *,
        joint_order: Sequence[str] | None = None,
        profile: RobotProfile | None = None,
    ) -> None: ...


class Traits(Flag):
    """What a format's files hold besides the homing offsets."""

    NONE = 0
    DIRECTIONS = auto()
    """A direction per joint."""
    IDS = auto()
    """A motor id per joint."""
    SELF_CONTAINED = auto()
    """A file reads back without a URDF, profile or joint order."""


@dataclass(frozen=True)
class FormatSpec:
    """One calibration file format, as the registry knows it (the format's module describes the format).

    Attributes:
        name: The format name users pass (``--from``/``--to``).
        reader: Reads a file of this format.
        writer: Writes one; None for a read-only format.
        sniff: True when parsed content (see :class:`Content`) is this format; may raise
            :class:`FileFormatError` for a file that must not be taken for any calibration.
        sniff_rank: Sniffers run in ascending rank (then registry order): 0 a format tag, 1 a distinctive
            key, 2 only the shape of the data.
        suffixes: File suffixes (lower case) a new destination of this format is recognised by.
        traits: What the files hold (:class:`Traits`).
    """

    name: str
    reader: Reader
    writer: Writer | None
    sniff: Callable[[Content], bool]
    sniff_rank: int
    suffixes: tuple[str, ...] = ()
    traits: Traits = Traits.NONE

    @property
    def self_contained(self) -> bool:
        """A file reads back without a URDF, profile or joint order."""
        return Traits.SELF_CONTAINED in self.traits

    @property
    def stores_directions(self) -> bool:
        """The file holds a direction per joint."""
        return Traits.DIRECTIONS in self.traits

    @property
    def stores_ids(self) -> bool:
        """The file holds a motor id per joint."""
        return Traits.IDS in self.traits


def first_value(data: Mapping[Any, Any]) -> Any:
    """The value of a mapping's first entry (None when it is empty)."""
    return next(iter(data.values()), None)


def check_unique_ids(ids: Mapping[str, int], source: str) -> None:
    """Refuse two joints with the same motor id."""
    seen: dict[int, str] = {}
    for name, mid in ids.items():
        if mid in seen:
            raise FileFormatError(f"{source}: joints {seen[mid]!r} and {name!r} share id {mid}")
        seen[mid] = name


def require_rad(cal: RobotCalibration, fmt: str) -> None:
    """Refuse a calibration with a scale other than 1 for a format that stores rad offsets only."""
    bad = [n for n, s in zip(cal.joint_names, cal.scale, strict=True) if s != 1.0]
    if bad:
        raise UsageError(
            f"format {fmt} stores offsets in the motor's rad frame (scale 1); joints {', '.join(bad)} have a "
            "different scale; use --to robocal"
        )


def ids_from(
    cal: RobotCalibration,
    ids: Mapping[str, int],
    urdf: UrdfModel | None,
    profile: RobotProfile | None = None,
) -> dict[str, int]:
    """Motor ids: the calibration's own, else the URDF's ``id``/``can_id`` params, else the profile's."""
    out: dict[str, int] = {}
    for name in cal.joint_names:
        mid = int(ids[name]) if name in ids else joint_motor_id(name, urdf, profile)
        if mid is not None:
            out[name] = mid
    return out


def yaml_data(path: Path, parsed: Any) -> Any:
    """The file's YAML document: ``parsed`` when format detection already parsed it (parse once), else load."""
    if parsed is not None:
        return parsed
    return load_yaml(read_text(path, "calibration file", limit=MAX_DOCUMENT_BYTES), str(path), item="joint")
