"""The calibration format registry: the one path for detecting, reading and writing joint-map files.

Each format lives in its own module and defines a :class:`~._base.FormatSpec`; :data:`FORMATS` maps the format
names to them (the order is the order of help texts and messages). Detection parses a file once (JSON object,
YAML mapping or XML) and asks the formats' sniffers, most specific first; a new destination's format comes from
the suffixes the specs declare.
"""

from __future__ import annotations

import json
import os
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from ...core.jointmap import RobotCalibration
from ...core.profile import RobotProfile
from ...errors import CalibError, FileFormatError, InvalidCalibrationError, UsageError
from ...fileio import MAX_DOCUMENT_BYTES, read_text
from .._json import is_valid_unicode, json_int, load_json
from .._yaml import load_yaml
from ..profiles import resolve_profile
from ..urdf import UrdfModel
from . import (
    berkeley,
    canonical,
    lerobot_legacy,
    lite_json,
    lite_yaml,
    openarm_lerobot,
    openarm_ros2,
    transmission,
)
from ._base import CalibrationFile, Content, FormatSpec, first_value

FORMATS: dict[str, FormatSpec] = {
    spec.name: spec
    for spec in (
        lite_json.SPEC,
        lite_yaml.SPEC,
        berkeley.SPEC,
        transmission.SPEC,
        lerobot_legacy.SPEC,
        canonical.SPEC,
        openarm_lerobot.SPEC,
        openarm_ros2.SPEC,
    )
}
"""Every joint-map format by name."""


@dataclass(frozen=True)
class NotAJointMap:
    """A file robocal recognises but cannot read as a joint map, and what to do with it instead."""

    name: str
    sniff: Callable[[Content], bool]
    advice: str


def _is_current_lerobot(content: Content) -> bool:
    first = first_value(content.data) if content.kind == "json" else None
    return isinstance(first, dict) and "range_min" in first


NOT_JOINT_MAPS = (
    NotAJointMap(
        "lerobot",
        _is_current_lerobot,
        "a current LeRobot calibration (range_min/range_max) is not a joint map; "
        "use 'robocal lerobot export-urdf' to derive one",
    ),
)
"""Recognised after every format's sniffer has declined."""


def _check_fmt(fmt: str) -> FormatSpec:
    if fmt not in FORMATS:
        raise UsageError(f"unknown format {fmt!r}; valid: {', '.join(FORMATS)}")
    return FORMATS[fmt]


def _parse_for_sniffing(text: str, source: str) -> Content | None:
    """The content to sniff: an XML start, a JSON object, else a YAML mapping (None: none of them)."""
    stripped = text.lstrip("\ufeff \t\r\n")
    if stripped.startswith("<"):
        return Content("xml", None, source)
    if stripped.startswith(("{", "[")):
        try:
            data = json.loads(stripped, parse_int=json_int)
        except (ValueError, RecursionError):  # reported by the real reader below
            data = None
        if isinstance(data, dict):
            return Content("json", data, source)
    try:
        data = load_yaml(text, source, item="joint")
    except FileFormatError:
        if stripped.startswith(("{", "[")) and not source.lower().endswith((".yaml", ".yml")):
            load_json(stripped, source)  # raises: report the JSON syntax error (line, column)
        raise  # a YAML syntax error is reported as such (line, column), not as an unknown format
    return Content("yaml", data, source) if isinstance(data, Mapping) else None


def _sniff(text: str, source: str) -> tuple[str | None, Any]:
    """The format of ``text`` and, when it was parsed as YAML to tell, the YAML document (else None).

    The name is a key of :data:`FORMATS`, the name of a :data:`NOT_JOINT_MAPS` entry, or None.
    """
    content = _parse_for_sniffing(text, source)
    if content is None:
        return None, None
    reuse = content.data if content.kind == "yaml" else None
    ranked = sorted(
        FORMATS.values(), key=lambda spec: spec.sniff_rank
    )  # stable: registry order within a rank
    for spec in ranked:
        if spec.sniff(content):
            return spec.name, reuse
    for other in NOT_JOINT_MAPS:
        if other.sniff(content):
            return other.name, None
    return None, None


def detect_format(path: str | os.PathLike[str]) -> str:
    """Guess the format of an existing calibration file from its content.

    Raises:
        FileFormatError: The file cannot be read or matches no known format.
    """
    return _detect(path)[0]


def _detect(path: str | os.PathLike[str]) -> tuple[str, Any]:
    """The format and, for YAML formats, the parsed document (so the reader does not parse it again)."""
    source = str(path)
    text = read_text(path, "calibration file", limit=MAX_DOCUMENT_BYTES)
    fmt, data = _sniff(text, source)
    for other in NOT_JOINT_MAPS:
        if fmt == other.name:
            raise FileFormatError(f"{source}: {other.advice}")
    if fmt is None:
        raise FileFormatError(
            f"{source}: unrecognised calibration format (known: {', '.join(FORMATS)}); "
            "name it explicitly if it is one of them (robocal convert --from)"
        )
    return fmt, data


def _format_for_output(path: Path) -> str:
    """An existing writable calibration's own format, else the format the suffix names."""
    if os.path.exists(path) and os.path.getsize(path) > 0:
        try:
            fmt = detect_format(path)
            if FORMATS[fmt].writer is not None:
                return fmt
        except FileFormatError:
            pass
    suffix = path.suffix.lower()
    for spec in FORMATS.values():
        if spec.writer is not None and suffix in spec.suffixes:
            return spec.name
    raise UsageError(f"cannot tell the format of {path} from its name; pass --to ({', '.join(FORMATS)})")


def read_calibration(
    path: str | os.PathLike[str],
    fmt: str | None = None,
    *,
    urdf: UrdfModel | None = None,
    joint_order: Sequence[str] | None = None,
    robot: str | os.PathLike[str] | RobotProfile | None = None,
) -> CalibrationFile:
    """Read a calibration file of any supported format into the canonical joint map.

    Args:
        path: The file.
        fmt: Format name (see :data:`FORMATS`); detected from the content when None.
        urdf: Supplies directions and ids for formats that lack them (``berkeley-offsets``); its
            ``direction``/``id`` params come before the profile's.
        joint_order: Joint order for positional formats (overrides the profile's order).
        robot: Robot profile (name, path or :class:`RobotProfile`); when None, the built-in profile the URDF's
            joint names match, if any. Gives joint order, directions and ids where the file and URDF lack them.

    Returns:
        The calibration with the ids the file (or URDF) gave.

    Raises:
        FileFormatError: Malformed file, naming the file, joint and field.
        UsageError: Unknown format, or a positional format without a joint order.
    """
    p = Path(path)
    parsed: Any = None
    if fmt is None:
        fmt, parsed = _detect(p)
    spec = _check_fmt(fmt)
    profile = resolve_profile(robot, urdf)
    try:
        if parsed is not None:
            return spec.reader(p, urdf=urdf, joint_order=joint_order, profile=profile, parsed_yaml=parsed)
        return spec.reader(p, urdf=urdf, joint_order=joint_order, profile=profile)
    except InvalidCalibrationError as exc:
        raise FileFormatError(f"{p}: {exc}") from None


def write_calibration(
    path: str | os.PathLike[str],
    data: CalibrationFile | RobotCalibration,
    fmt: str | None = None,
    *,
    urdf: UrdfModel | None = None,
    ids: Mapping[str, int] | None = None,
    joint_order: Sequence[str] | None = None,
    robot: str | os.PathLike[str] | RobotProfile | None = None,
    what: str = "destination",
) -> str:
    """Write a calibration atomically (keeping ``NAME.bak``), in place where the format allows.

    An existing ``lite-yaml`` file is updated in place: comments, key order and untouched values stay as
    they were, and only changed values change. An existing URDF gets its ``<transmission>`` elements updated.
    An existing file that is not a calibration of the format written is refused (see
    :func:`read_existing_output`, the one rule ``convert`` and ``sweep --out`` share).

    Args:
        path: Destination.
        data: The calibration (optionally with ids).
        fmt: Format name; when None, the existing file's format, else the file suffix.
        urdf: Supplies ids (``id``/``can_id`` params) where ``data`` has none; base document for URDF output.
        ids: Extra motor ids, overriding those in ``data``.
        joint_order: Order for positional formats (``berkeley-offsets``: else the profile's order; never the
            URDF's document order).
        robot: Robot profile (name, path or :class:`RobotProfile`); when None, the built-in profile the URDF's
            joint names match, if any. Supplies the order of positional formats and ids the data and URDF lack.
        what: How messages name ``path`` (``"--out"``).

    Returns:
        The format written.

    Raises:
        FileFormatError: ``path`` exists and is not a calibration of the format written; nothing is written.
    """
    p = Path(path)
    cf = data if isinstance(data, CalibrationFile) else CalibrationFile(data)
    if ids:
        cf = CalibrationFile(cf.calibration, {**cf.ids, **ids}, cf.fmt, cf.source, cf.notes, cf.ranges_rad)
    name = fmt if fmt is not None else _format_for_output(p)
    spec = _check_fmt(name)
    if spec.writer is None:
        raise UsageError(
            f"format {name} is read-only; valid output formats: "
            f"{', '.join(k for k, v in FORMATS.items() if v.writer is not None)}"
        )
    bad = [n for n in cf.calibration.joint_names if not is_valid_unicode(n)]
    if bad:
        raise InvalidCalibrationError(
            f"cannot write {p}: joint name {bad[0]!a} is not valid Unicode (a lone surrogate); nothing written"
        )
    profile = resolve_profile(robot, urdf)
    read_existing_output(p, name, what, urdf=urdf, joint_order=joint_order, robot=profile)
    spec.writer(p, cf, urdf, joint_order=joint_order, profile=profile)
    return name


def read_existing_output(
    path: str | os.PathLike[str],
    fmt: str,
    what: str = "destination",
    *,
    urdf: UrdfModel | None = None,
    joint_order: Sequence[str] | None = None,
    robot: str | os.PathLike[str] | RobotProfile | None = None,
    advice: str | None = None,
) -> CalibrationFile | None:
    """The one rule for writing over an existing file: it must be a calibration of the format written.

    A missing file, an empty one or one holding only ``#`` comments may be written. Any other file must be
    recognised as ``fmt`` by its content; ``lite-json``, ``lite-yaml`` and ``robocal`` files must also read
    without error (``berkeley-offsets`` is positional and ``ros2-transmission`` a URDF that may have no
    transmission yet, so for those recognising the format is enough). ``robocal convert`` (through
    :func:`write_calibration`) and ``robocal sweep --out`` (before the sweep starts) both apply it.

    Args:
        path: The destination.
        fmt: The format that will be written.
        what: How the message names the destination (``"--out"``, ``"destination"``).
        urdf: URDF for reading the existing file (directions, ids).
        joint_order: Joint order for positional formats.
        robot: Robot profile for reading the existing file.
        advice: What the refusal tells the user to do (default: move the file away or choose another
            destination); a caller that only reads the file (``sweep --auto --verify``) says what it needs instead.

    Returns:
        The calibration the file holds (for the self-contained formats), else None.

    Raises:
        FileFormatError: The file holds something else; nothing is written. The message says what it looks
            like and to move it away or choose another destination.
    """
    p = Path(path)
    if not os.path.exists(p):  # os.path: a name too long is "missing" here and refused by the writer
        return None
    text = read_text(p, what, limit=MAX_DOCUMENT_BYTES)
    if all(not ln.strip() or ln.lstrip().startswith("#") for ln in text.splitlines()):
        return None  # empty, or only comments: nothing to keep

    todo = advice or f"move it away or choose another {'--out' if what == '--out' else 'destination'}"

    def refuse(why: str) -> FileFormatError:
        return FileFormatError(f"{what} {p}: exists but is not a {fmt} calibration file ({why}); {todo}")

    try:
        found, _doc = _sniff(text, str(p))
    except FileFormatError as exc:
        raise refuse(str(exc)) from None
    if found != fmt:
        raise refuse(f"it looks like {found}" if found else "not a calibration format robocal knows")
    spec = FORMATS.get(fmt)
    if spec is None or not spec.self_contained:
        return None
    try:
        return read_calibration(p, fmt, urdf=urdf, joint_order=joint_order, robot=robot)
    except CalibError as exc:
        raise refuse(str(exc)) from None
