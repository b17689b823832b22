"""Robot profile files: read, validate, find by name, recognise from a URDF's joint names.

A profile is a YAML file (schema in ``docs/profiles.md``); the built-in ones live in
``robocal/data/profiles/NAME.yaml``. ``--robot`` takes a built-in name or the path of a profile file.
"""

from __future__ import annotations

import functools
import math
import os
from collections.abc import Iterable, Mapping
from importlib import resources
from pathlib import Path
from typing import Any

from ..core.profile import (
    LEGACY_MODES,
    LEROBOT_KINDS,
    LEROBOT_VENDORS,
    METHODS,
    NORM_MODES,
    STOPS,
    LeRobotSection,
    ProfileJoint,
    RobotProfile,
)
from ..errors import FileFormatError, UsageError
from ..fileio import MAX_DOCUMENT_BYTES, read_text
from ._numbers import parse_direction, parse_finite, parse_int, parse_motor_id
from ._profile_auto import check_known_keys, parse_auto_section
from ._shipped_yaml import load_shipped
from ._yaml import load_yaml
from .urdf import UrdfModel

__all__ = [
    "PROFILE_FORMAT_TAG",
    "SUPPORTED_VERSIONS",
    "builtin_lerobot_profiles",
    "builtin_profile_names",
    "builtin_profiles",
    "joint_direction",
    "joint_motor_id",
    "load_profile",
    "parse_profile",
    "profile_for_joints",
    "recognise_profile",
    "resolve_profile",
]

PROFILE_FORMAT_TAG = "robocal-robot-profile"
_TOP_KEYS = (
    "format",
    "version",
    "name",
    "description",
    "upstream",
    "actuator",
    "position_wraps",
    "calibration",
    "joints",
)
_CAL_KEYS = ("method", "file_format")
_JOINT_KEYS = ("name", "upstream_name", "bus", "id", "direction", "model", "stop", "stop_deg")
_LEROBOT_KEYS = (
    "device_name",
    "old_device_name",
    "kind",
    "vendor",
    "operating_mode",
    "full_turn",
    "inverted",
    "robot_types",
)
_LEROBOT_JOINT_KEYS = ("norm_mode", "legacy_mode", "operating_mode", "position_gains")
SUPPORTED_VERSIONS = (1, 2)
"""Schema versions this robocal reads; version 2 adds the ``lerobot`` and ``auto_calibration`` sections and the
``lerobot`` per-joint keys."""
_SECTION_VERSIONS: dict[str, int] = {"lerobot": 2, "auto_calibration": 2}
"""Optional top-level sections → the first schema version that has them (a section is a further key here,
a parser below and a field of :class:`RobotProfile`)."""
_JOINT_KEY_VERSIONS: dict[str, int] = {**dict.fromkeys(_LEROBOT_JOINT_KEYS, 2), "reply_id": 2}


def _opt_str(entry: Mapping[str, Any], key: str, where: str) -> str | None:
    value = entry.get(key)
    if value is None:
        return None
    if not isinstance(value, str) or not value.strip():
        raise FileFormatError(f"{where}: {key} {value!r} must be a non-empty string")
    return value.strip()


def _choice(entry: Mapping[str, Any], key: str, choices: tuple[str, ...], where: str) -> str | None:
    value = _opt_str(entry, key, where)
    if value is not None and value not in choices:
        raise FileFormatError(f"{where}: {key} {value!r}; expected one of {', '.join(choices)}")
    return value


def _joint(entry: Any, i: int, source: str, version: int) -> ProfileJoint:
    allowed = _JOINT_KEYS + tuple(k for k, v in _JOINT_KEY_VERSIONS.items() if version >= v)
    where = f"profile {source}: joints[{i}]"
    if not isinstance(entry, Mapping):
        raise FileFormatError(f"{where}: expected a mapping with keys {', '.join(allowed)}")
    name = _opt_str(entry, "name", where)
    if name is None:
        raise FileFormatError(f"{where}: missing key name (the joint's URDF name)")
    where = f"profile {source}: joint {name!r}"
    check_known_keys(entry, allowed, where)
    stop = _opt_str(entry, "stop", where)
    if stop is not None and stop not in STOPS:
        raise FileFormatError(f"{where}: stop {stop!r}; expected {' or '.join(STOPS)}")
    stop_deg = None if entry.get("stop_deg") is None else parse_finite(entry["stop_deg"], where, "stop_deg")
    if (stop is None) != (stop_deg is None):
        raise FileFormatError(f"{where}: stop and stop_deg go together (give both or neither)")
    return ProfileJoint(
        name=name,
        upstream_name=_opt_str(entry, "upstream_name", where) or name,
        bus=_opt_str(entry, "bus", where),
        motor_id=None if entry.get("id") is None else parse_motor_id(entry["id"], where),
        reply_id=None if entry.get("reply_id") is None else parse_motor_id(entry["reply_id"], where, "reply_id"),
        direction=None if entry.get("direction") is None else parse_direction(entry["direction"], where),
        model=_opt_str(entry, "model", where),
        stop=stop,
        stop_deg=stop_deg,
        norm_mode=_choice(entry, "norm_mode", NORM_MODES, where),
        legacy_mode=_choice(entry, "legacy_mode", LEGACY_MODES, where),
        operating_mode=None if entry.get("operating_mode") is None else _register_value(entry, "operating_mode", where),
        position_gains=_position_gains(entry, where),
    )


def _register_value(entry: Mapping[str, Any], key: str, where: str, limit: int = 65535) -> int:
    value = parse_int(entry[key], where, key)
    if not 0 <= value <= limit:
        raise FileFormatError(f"{where}: {key} {value} is out of range; expected 0..{limit} (a register value)")
    return value


def _position_gains(entry: Mapping[str, Any], where: str) -> tuple[int, int, int] | None:
    """A motor's ``position_gains: [P, I, D]`` (register values), or None."""
    value = entry.get("position_gains")
    if value is None:
        return None
    if not isinstance(value, list) or len(value) != 3:
        raise FileFormatError(f"{where}: position_gains {value!r}; expected [P, I, D] (three register values)")
    p, i, d = (_register_value({"position_gains": v}, "position_gains", where) for v in value)
    return p, i, d


def _name_list(section: Mapping[str, Any], key: str, where: str) -> tuple[str, ...]:
    value = section.get(key)
    if value is None:
        return ()
    if not isinstance(value, list) or not all(isinstance(v, str) and v.strip() for v in value):
        raise FileFormatError(f"{where}: {key} {value!r}; expected a list of names")
    return tuple(v.strip() for v in value)


def _lerobot_section(data: Any, joints: tuple[ProfileJoint, ...], source: str) -> LeRobotSection:
    """The ``lerobot:`` section: every key required but the lists; joints need ``id``, ``model``, ``norm_mode``."""
    where = f"profile {source}: lerobot"
    if not isinstance(data, Mapping):
        raise FileFormatError(f"{where}: expected a mapping with keys {', '.join(_LEROBOT_KEYS)}")
    check_known_keys(data, _LEROBOT_KEYS, where)
    required = {}
    for key in ("device_name", "old_device_name"):
        value = _opt_str(data, key, where)
        if value is None:
            raise FileFormatError(f"{where}: missing key {key}")
        required[key] = value
    kind = _choice(data, "kind", LEROBOT_KINDS, where)
    vendor = _choice(data, "vendor", LEROBOT_VENDORS, where)
    if kind is None or vendor is None:
        raise FileFormatError(f"{where}: missing key {'kind' if kind is None else 'vendor'}")
    if data.get("operating_mode") is None:
        raise FileFormatError(f"{where}: missing key operating_mode")
    operating_mode = parse_int(data["operating_mode"], where, "operating_mode")
    names = {j.name for j in joints}
    lists = {k: _name_list(data, k, where) for k in ("full_turn", "inverted")}
    for key, listed in lists.items():
        unknown = [n for n in listed if n not in names]
        if unknown:
            raise FileFormatError(f"{where}: {key} names no joint of the profile: {', '.join(unknown)}")
    for j in joints:
        lacking = [
            k
            for k, v in (("id", j.motor_id), ("model", j.model), ("norm_mode", j.norm_mode))
            if v is None
        ]
        if lacking:
            raise FileFormatError(
                f"profile {source}: joint {j.name!r}: a LeRobot arm needs {', '.join(lacking)}"
            )
    return LeRobotSection(
        device_name=required["device_name"],
        old_device_name=required["old_device_name"],
        kind=kind,
        vendor=vendor,
        operating_mode=operating_mode,
        full_turn=lists["full_turn"],
        inverted=lists["inverted"],
        robot_types=tuple(t.lower() for t in _name_list(data, "robot_types", where)),
    )


def parse_profile(data: Any, source: str) -> RobotProfile:
    """Validate a profile document (the YAML already loaded) into a :class:`RobotProfile`.

    Raises:
        FileFormatError: Naming the file, the joint and the field that is wrong.
    """
    if not isinstance(data, Mapping) or data.get("format") != PROFILE_FORMAT_TAG:
        raise FileFormatError(
            f"profile {source}: not a robot profile (expected 'format: {PROFILE_FORMAT_TAG}')"
        )
    version = data.get("version")
    if isinstance(version, bool) or version not in SUPPORTED_VERSIONS:
        raise FileFormatError(
            f"profile {source}: version {version!r} is not supported "
            f"(expected {' or '.join(map(str, SUPPORTED_VERSIONS))})"
        )
    if version < 2 and "auto_calibration" in data:
        raise FileFormatError(
            f"profile {source}: the auto_calibration section needs version 2 (this file says version {version})"
        )
    check_known_keys(
        data, _TOP_KEYS + tuple(k for k, v in _SECTION_VERSIONS.items() if version >= v), f"profile {source}"
    )
    name = _opt_str(data, "name", f"profile {source}")
    if name is None:
        raise FileFormatError(f"profile {source}: missing key name")
    cal = data.get("calibration") or {}
    if not isinstance(cal, Mapping):
        raise FileFormatError(f"profile {source}: calibration must be a mapping ({', '.join(_CAL_KEYS)})")
    check_known_keys(cal, _CAL_KEYS, f"profile {source}: calibration")
    method = _opt_str(cal, "method", f"profile {source}: calibration") or "two-sided"
    if method not in METHODS:
        raise FileFormatError(
            f"profile {source}: calibration method {method!r}; expected {' or '.join(METHODS)}"
        )
    file_format = _opt_str(cal, "file_format", f"profile {source}: calibration")
    wraps = data.get("position_wraps", True)
    if not isinstance(wraps, bool):
        raise FileFormatError(f"profile {source}: position_wraps {wraps!r}; expected true or false")
    rows = data.get("joints")
    if not isinstance(rows, list) or not rows:
        raise FileFormatError(f"profile {source}: joints must be a non-empty list")
    joints = tuple(_joint(e, i, source, version) for i, e in enumerate(rows))
    for attr, what in (("name", "name"), ("upstream_name", "upstream_name")):
        seen: set[str] = set()
        for j in joints:
            value = getattr(j, attr)
            if value in seen:
                raise FileFormatError(f"profile {source}: {what} {value!r} appears twice")
            seen.add(value)
    owners: dict[tuple[str | None, int], str] = {}
    for j in joints:
        if j.motor_id is not None:
            other = owners.setdefault((j.bus, j.motor_id), j.name)
            if other != j.name:
                raise FileFormatError(
                    f"profile {source}: joints {other!r} and {j.name!r} share id {j.motor_id} on bus {j.bus}"
                )
    profile = RobotProfile(
        name=name,
        description=_opt_str(data, "description", f"profile {source}") or "",
        joints=joints,
        method=method,
        file_format=file_format,
        actuator=_opt_str(data, "actuator", f"profile {source}"),
        position_wraps=wraps,
        upstream=_opt_str(data, "upstream", f"profile {source}") or "",
        source=source,
        lerobot=None if data.get("lerobot") is None else _lerobot_section(data["lerobot"], joints, source),
        version=version,
        auto=None
        if data.get("auto_calibration") is None
        else parse_auto_section(data["auto_calibration"], joints, source),
    )
    if method == "one-sided" and profile.one_sided_ready():
        raise FileFormatError(
            f"profile {source}: method one-sided needs stop and stop_deg for every joint; missing for "
            f"{', '.join(profile.one_sided_ready())}"
        )
    for j in joints:
        if j.stop_deg is not None and not math.isfinite(
            j.stop_deg
        ):  # pragma: no cover - parse_finite refuses
            raise FileFormatError(f"profile {source}: joint {j.name!r}: stop_deg must be finite")
    return profile


def _read_profile_file(path: Path) -> RobotProfile:
    source = str(path)
    return parse_profile(load_yaml(read_text(path, "robot profile", limit=MAX_DOCUMENT_BYTES), source), source)


def _builtin_dir() -> Any:
    return resources.files("robocal").joinpath("data").joinpath("profiles")


def builtin_profile_names() -> tuple[str, ...]:
    """Names of the profiles shipped with robocal, sorted."""
    return tuple(
        sorted(p.name[: -len(".yaml")] for p in _builtin_dir().iterdir() if p.name.endswith(".yaml"))
    )


@functools.cache
def _builtin(name: str) -> RobotProfile:
    res = _builtin_dir().joinpath(f"{name}.yaml")
    source = f"robocal:data/profiles/{name}.yaml"
    text = res.read_text(encoding="utf-8")
    data = load_shipped(text)  # the shipped layout, read quickly; anything else: the full reader
    profile = parse_profile(load_yaml(text, source) if data is None else data, source)
    if profile.name != name:  # pragma: no cover - a packaging mistake
        raise FileFormatError(f"profile {source}: its name is {profile.name!r}, expected {name!r}")
    return profile


def builtin_profiles() -> tuple[RobotProfile, ...]:
    """Every profile shipped with robocal."""
    return tuple(_builtin(n) for n in builtin_profile_names())


def builtin_lerobot_profiles() -> tuple[RobotProfile, ...]:
    """The built-in profiles of LeRobot arms (those with a ``lerobot`` section), sorted by name."""
    return tuple(p for p in builtin_profiles() if p.lerobot is not None)


def load_profile(robot: str | os.PathLike[str]) -> RobotProfile:
    """A profile by built-in name (``bhl_biped``) or by path of a profile YAML file.

    Raises:
        UsageError: Neither a built-in name nor an existing file (the message lists the built-in names).
        FileFormatError: The file is not a valid profile.
    """
    text = os.fspath(robot)
    names = builtin_profile_names()
    if text in names:
        return _builtin(text)
    path = profile_file(text)
    if path is not None:
        return _read_profile_file(path)
    raise UsageError(
        f"--robot {text!r}: not a built-in robot ({', '.join(names)}) and not a profile file; "
        "see docs/profiles.md to write your own"
    )


def profile_file(robot: object) -> Path | None:
    """The file ``--robot`` names when it is a profile file (what :func:`load_profile` would read), else None."""
    if isinstance(robot, (str, os.PathLike)) and os.fspath(robot) not in builtin_profile_names():
        path = Path(robot)
        return path if path.is_file() else None
    return None


def recognise_profile(urdf: UrdfModel) -> RobotProfile | None:
    """The built-in profile whose joints are all in ``urdf`` (the one with most joints), or None.

    LeRobot arm profiles are not recognised (their six motor names are shared by every LeRobot arm); pass
    ``--robot`` for those. Profiles with the very same joints (an OpenArm follower and leader: names, ids,
    directions) are one match: the first by name is taken.

    Raises:
        UsageError: Two profiles with the same number of joints both match (pass ``--robot``).
    """
    names = set(urdf.joint_names)
    found = [p for p in builtin_profiles() if p.lerobot is None and p.matches(names)]
    if not found:
        return None
    found.sort(key=lambda p: (-len(p.joints), p.name))
    if len(found) > 1 and len(found[0].joints) == len(found[1].joints) and found[0].joints != found[1].joints:
        raise UsageError(
            f"URDF {urdf.source} matches robots {found[0].name} and {found[1].name}; pass --robot NAME"
        )
    return found[0]


def profile_for_joints(joint_names: Iterable[str]) -> RobotProfile | None:
    """The built-in profile with exactly these joints (in any order), or None (LeRobot arms are not guessed)."""
    have = set(joint_names)
    for p in builtin_profiles():
        if p.lerobot is None and set(p.joint_names) == have:
            return p
    return None


def resolve_profile(
    robot: str | os.PathLike[str] | RobotProfile | None, urdf: UrdfModel | None
) -> RobotProfile | None:
    """The profile in effect: ``robot`` (name, path or profile) if given, else the one the URDF matches.

    An explicit profile must name joints the URDF has.

    Raises:
        UsageError, FileFormatError: see :func:`load_profile`.
        JointMismatchError: ``--robot`` names joints the URDF lacks.
    """
    if robot is None:
        return recognise_profile(urdf) if urdf is not None else None
    profile = robot if isinstance(robot, RobotProfile) else load_profile(robot)
    if urdf is not None:
        lacking = [n for n in profile.joint_names if n not in urdf.joint_names]
        if lacking:
            from ..errors import JointMismatchError

            raise JointMismatchError(
                f"--robot {profile.name}: URDF {urdf.source} has no joint {', '.join(lacking)}"
            )
    return profile


def joint_direction(
    name: str,
    urdf: UrdfModel | None,
    profile: RobotProfile | None,
    file_directions: Mapping[str, int] | None = None,
) -> int | None:
    """A joint's direction by robocal's one precedence: the URDF, else the calibration file, else the profile.

    Args:
        name: URDF joint name.
        urdf: The URDF (its ``<param name='direction'>``), or None.
        profile: The robot profile in effect, or None.
        file_directions: Joint → direction of a calibration file whose format stores one, or None.

    Returns:
        ±1, or None when no source has a direction for ``name``.

    Raises:
        FileFormatError: The URDF's ``direction`` param is not ±1.
    """
    d = urdf.direction(name) if urdf is not None else None
    if d is None and file_directions is not None:
        d = file_directions.get(name)
    if d is None and profile is not None:
        d = profile.direction(name)
    return d


def joint_motor_id(name: str, urdf: UrdfModel | None, profile: RobotProfile | None) -> int | None:
    """A joint's motor (CAN) id: the URDF's ``id``/``can_id``/``motor_id`` param, else the profile's, else None.

    Raises:
        FileFormatError: The URDF's id param is not a valid id.
    """
    mid = urdf.motor_id(name) if urdf is not None else None
    if mid is None and profile is not None:
        mid = profile.motor_id(name)
    return mid
