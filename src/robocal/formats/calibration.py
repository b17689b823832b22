"""Calibration files: read, write and detect every joint-map format robocal converts between.

=====================  ==========================================================================================
``lite-json``          Lite-Lowlevel-Python ``calibration.json``: ``{joint: {id, direction, homing_offset}}``
``lite-yaml``          Humanoid-Control ``calibration.yaml``, same schema; updated in place keeping comments
``berkeley-offsets``   Berkeley-Humanoid-Lite-Lowlevel ``{"position_offsets": [...]}``: joint-frame, positional
``ros2-transmission``  URDF ``<transmission>`` with ``SimpleTransmission`` (``mechanical_reduction``, ``offset``)
``lerobot-legacy``     LeRobot legacy array JSON (read only); DEGREE joints convert exactly
``robocal``            robocal's canonical joint map YAML (direction, homing_offset, scale per joint)
=====================  ==========================================================================================

Every reader validates the whole file before returning; every writer validates before writing, writes atomically
and keeps ``NAME.bak``.
"""

from __future__ import annotations

import json
import os
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from types import MappingProxyType
from typing import Any

import numpy as np
from lxml import etree

from ..core.conventions import (
    berkeley_offset_from_homing,
    homing_from_berkeley_offset,
)
from ..core.jointmap import RobotCalibration
from ..core.profile import RobotProfile
from ..errors import CalibError, FileFormatError, InvalidCalibrationError, JointMismatchError, UsageError
from ..fileio import atomic_write_bytes, atomic_write_text, read_bytes, read_text
from ._json import is_valid_unicode, load_json
from ._numbers import format_float, parse_direction, parse_finite, parse_motor_id
from ._yaml import dump_yaml, load_yaml
from .profiles import profile_for_joints, resolve_profile
from .urdf import UrdfDocument, UrdfModel, _model_from_tree, _parse_tree

__all__ = [
    "FORMATS",
    "CalibrationFile",
    "detect_format",
    "read_calibration",
    "read_existing_output",
    "write_calibration",
]

LITE_KEYS = ("id", "direction", "homing_offset")
ROBOCAL_FORMAT_TAG = "robocal-joint-map"


@dataclass(frozen=True)
class CalibrationFile:
    """A joint calibration together with what its file said about the joints.

    Attributes:
        calibration: The canonical joint map.
        ids: Motor id per joint where the file (or URDF) gives one.
        fmt: Format name the data was read from (or is meant for).
        source: Path or description of the origin.
        notes: Human-readable remarks made while reading (e.g. values taken from the URDF).
    """

    calibration: RobotCalibration
    ids: Mapping[str, int] = field(default_factory=dict)
    fmt: str = "robocal"
    source: str = "<memory>"
    notes: tuple[str, ...] = ()


# ------------------------------------------------------------------------------------------------- helpers
def _check_unique_ids(ids: Mapping[str, int], source: str) -> None:
    seen: dict[int, str] = {}
    for name, mid in ids.items():
        if mid in seen:
            raise FileFormatError(f"{source}: joints {seen[mid]!r} and {name!r} share id {mid}")
        seen[mid] = name


def _require_rad(cal: RobotCalibration, fmt: str) -> None:
    bad = [n for n, s in zip(cal.joint_names, cal.scale, strict=True) if s != 1.0]
    if bad:
        raise UsageError(
            f"format {fmt} stores offsets in the motor's rad frame (scale 1); joints {', '.join(bad)} have a "
            "different scale; use --to robocal"
        )


def _ids_from(
    cal: RobotCalibration,
    ids: Mapping[str, int],
    urdf: UrdfModel | None,
    profile: RobotProfile | None = None,
) -> dict[str, int]:
    """Motor ids: the calibration's own, else the URDF's ``id``/``can_id`` params, else the profile's."""
    out: dict[str, int] = {}
    for name in cal.joint_names:
        if name in ids:
            out[name] = int(ids[name])
        elif urdf is not None and name in urdf.joint_params and urdf.motor_id(name) is not None:
            out[name] = int(urdf.motor_id(name))  # type: ignore[arg-type]
        elif profile is not None and profile.motor_id(name) is not None:
            out[name] = int(profile.motor_id(name))  # type: ignore[arg-type]
    return out


# ------------------------------------------------------------------------------------------------ lite-*
def _parse_lite(data: Any, source: str, fmt: str) -> CalibrationFile:
    if not isinstance(data, Mapping) or not data:
        raise FileFormatError(
            f"{source}: expected a mapping of joint name -> {{id, direction, homing_offset}}"
        )
    names: list[str] = []
    dirs: list[int] = []
    offs: list[float] = []
    ids: dict[str, int] = {}
    for name, entry in data.items():
        if not isinstance(name, str) or not name:
            raise FileFormatError(f"{source}: joint name {name!r} is not a string")
        where = f"{source}: joint {name!r}"
        if not isinstance(entry, Mapping):
            raise FileFormatError(f"{where}: expected a mapping with keys id, direction, homing_offset")
        missing = [k for k in ("direction", "homing_offset") if k not in entry]
        if missing:
            raise FileFormatError(f"{where}: missing key {', '.join(missing)}")
        extra = [str(k) for k in entry if k not in LITE_KEYS]
        if extra:
            raise FileFormatError(
                f"{where}: unknown key {', '.join(extra)}; expected id, direction, homing_offset"
            )
        if "id" in entry:
            ids[name] = parse_motor_id(entry["id"], where)
        dirs.append(parse_direction(entry["direction"], where))
        offs.append(parse_finite(entry["homing_offset"], where, "homing_offset"))
        names.append(name)
    _check_unique_ids(ids, source)
    return CalibrationFile(RobotCalibration(names, dirs, offs, 1.0), MappingProxyType(ids), fmt, source)


_MOTOR_CONFIG_KEYS = ("position_controller", "current_controller", "powerstage")


def _refuse_motor_configuration(data: object, source: str) -> None:
    """A Lite ``robot_configuration.json`` (per-joint controller settings, ``Infinity`` limits) is no calibration."""
    first = next(iter(data.values()), None) if isinstance(data, dict) else None
    if isinstance(first, dict) and any(k in first for k in _MOTOR_CONFIG_KEYS):
        raise FileFormatError(
            f"{source}: this is a motor configuration (per-joint {', '.join(k for k in _MOTOR_CONFIG_KEYS if k in first)}"
            " settings, like the Berkeley Humanoid Lite's robot_configuration.json), not a calibration"
        )


def _read_lite_json(path: Path, **_: Any) -> CalibrationFile:
    text = read_text(path, "calibration file")
    try:  # before its Infinity values fail the strict JSON reader
        loose = json.loads(text)
    except (ValueError, RecursionError):
        loose = None
    _refuse_motor_configuration(loose, str(path))
    return _parse_lite(load_json(text, str(path), item="joint"), str(path), "lite-json")


def _yaml_data(path: Path, parsed: Any) -> Any:
    """The file's YAML document: ``parsed`` when format detection already parsed it (parse once), else load."""
    if parsed is not None:
        return parsed
    return load_yaml(read_text(path, "calibration file"), str(path), item="joint")


def _read_lite_yaml(path: Path, parsed_yaml: Any = None, **_: Any) -> CalibrationFile:
    return _parse_lite(_yaml_data(path, parsed_yaml), str(path), "lite-yaml")


def _lite_entries(
    cf: CalibrationFile, urdf: UrdfModel | None, fmt: str, profile: RobotProfile | None = None
) -> dict[str, dict[str, Any]]:
    cal = cf.calibration
    _require_rad(cal, fmt)
    ids = _ids_from(cal, cf.ids, urdf, profile)
    missing = [n for n in cal.joint_names if n not in ids]
    if missing:
        if urdf is None and profile is None:
            hint = "pass --urdf with id/can_id params, or --robot NAME"
        elif urdf is None:
            hint = f"profile {profile.name} has none for them; pass --urdf with id/can_id params"  # type: ignore[union-attr]
        else:
            where = f"URDF {urdf.source} has no id/can_id param for them"
            where += f" and profile {profile.name} none either" if profile is not None else ""
            hint = f"{where}; pass --robot NAME or a profile file (docs/profiles.md)"
        raise UsageError(
            f"format {fmt} needs a motor id for every joint; missing for {', '.join(missing)} ({hint})"
        )
    _check_unique_ids(ids, f"calibration for {fmt}")
    return {
        n: {"id": ids[n], "direction": int(d), "homing_offset": float(h)}
        for n, d, h in zip(cal.joint_names, cal.direction, cal.homing_offset, strict=True)
    }


def _write_lite_json(
    path: Path, cf: CalibrationFile, urdf: UrdfModel | None, profile: RobotProfile | None = None, **_: Any
) -> None:
    entries = _lite_entries(cf, urdf, "lite-json", profile)
    for e in entries.values():
        if e["homing_offset"] == 0.0:
            e["homing_offset"] = 0.0  # normalise -0.0
    atomic_write_text(path, json.dumps(entries, indent=4) + "\n")


def _write_lite_yaml(
    path: Path, cf: CalibrationFile, urdf: UrdfModel | None, profile: RobotProfile | None = None, **_: Any
) -> None:
    entries = _lite_entries(cf, urdf, "lite-yaml", profile)
    doc: Any = None
    if path.exists():
        try:
            doc = load_yaml(read_text(path, "calibration file"), str(path), item="joint")
            _parse_lite(doc, str(path), "lite-yaml")
        except FileFormatError:
            doc = None  # not a lite-yaml file we can update: replace it (the old one is kept as .bak)
    if doc is None:
        from ruamel.yaml.comments import CommentedMap

        doc = CommentedMap()
    # the file holds exactly the calibration written, so reading it back gives the same joints
    for name in [k for k in doc if k not in entries]:
        del doc[name]
    for name, entry in entries.items():
        if name in doc:
            node = doc[name]
            for key in LITE_KEYS:
                old = node.get(key)
                new = entry[key]
                if old is None or isinstance(old, bool) or float(old) != float(new):
                    node[key] = new
        else:
            from ruamel.yaml.comments import CommentedMap

            node = CommentedMap()
            for key in LITE_KEYS:
                node[key] = entry[key]
            doc[name] = node
    atomic_write_text(path, dump_yaml(doc))


# ----------------------------------------------------------------------------------------------- robocal
def _read_robocal(path: Path, parsed_yaml: Any = None, **_: Any) -> CalibrationFile:
    source = str(path)
    data = _yaml_data(path, parsed_yaml)
    if not isinstance(data, Mapping) or data.get("format") != ROBOCAL_FORMAT_TAG:
        raise FileFormatError(f"{source}: not a robocal joint map (expected 'format: {ROBOCAL_FORMAT_TAG}')")
    version = data.get("version")
    if version != 1:
        raise FileFormatError(f"{source}: version {version!r} is not supported (expected 1)")
    joints = data.get("joints")
    if not isinstance(joints, Mapping) or not joints:
        raise FileFormatError(f"{source}: 'joints' must be a non-empty mapping")
    names, dirs, offs, scales = [], [], [], []
    ids: dict[str, int] = {}
    for name, entry in joints.items():
        where = f"{source}: joint {name!r}"
        if not isinstance(entry, Mapping):
            raise FileFormatError(f"{where}: expected a mapping")
        allowed = {"id", "direction", "homing_offset", "scale", "raw_unit", "joint_unit"}
        extra = [str(k) for k in entry if k not in allowed]
        if extra:
            raise FileFormatError(
                f"{where}: unknown key {', '.join(extra)}; expected {', '.join(sorted(allowed))}"
            )
        for key in ("direction", "homing_offset"):
            if key not in entry:
                raise FileFormatError(f"{where}: missing key {key}")
        if "id" in entry:
            ids[str(name)] = parse_motor_id(entry["id"], where)
        dirs.append(parse_direction(entry["direction"], where))
        offs.append(parse_finite(entry["homing_offset"], where, "homing_offset"))
        scale = parse_finite(entry.get("scale", 1.0), where, "scale")
        if scale <= 0:
            raise FileFormatError(f"{where}: scale {scale} must be > 0")
        scales.append(scale)
        names.append(str(name))
    _check_unique_ids(ids, source)
    return CalibrationFile(
        RobotCalibration(names, dirs, offs, scales), MappingProxyType(ids), "robocal", source
    )


def _write_robocal(
    path: Path, cf: CalibrationFile, urdf: UrdfModel | None, profile: RobotProfile | None = None, **_: Any
) -> None:
    cal = cf.calibration
    ids = _ids_from(cal, cf.ids, urdf, profile)
    lines = [
        "# robocal joint map: q_joint = direction * scale * (raw - homing_offset)",
        "# homing_offset is in the motor's raw unit; scale converts raw units to joint units (rad or m).",
        f"format: {ROBOCAL_FORMAT_TAG}",
        "version: 1",
        "joints:",
    ]
    from ._yaml import yaml_float

    for n, d, h, s in zip(cal.joint_names, cal.direction, cal.homing_offset, cal.scale, strict=True):
        lines.append(f"  {json.dumps(n)}:")
        if n in ids:
            lines.append(f"    id: {ids[n]}")
        lines.append(f"    direction: {int(d)}")
        lines.append(f"    homing_offset: {yaml_float(h)}")
        lines.append(f"    scale: {yaml_float(s)}")
    atomic_write_text(path, "\n".join(lines) + "\n")


# -------------------------------------------------------------------------------------- berkeley-offsets
BERKELEY_ORDER_COMMENT = "# joint order: "


def _no_order_message(what: str) -> str:
    from .profiles import builtin_profile_names

    return (
        f"{what}: berkeley-offsets is positional (its reader takes the offsets by index, in the order of the "
        "robot's low-level code, which is not the URDF's document order); pass --joints a,b,... for the order, "
        f"or --robot NAME for a robot robocal knows ({', '.join(builtin_profile_names())}) or a profile file"
    )


def _order_from_comment(text: str) -> list[str] | None:
    """The ``# joint order: a, b, ...`` line robocal writes at the top of a berkeley-offsets file, if any."""
    for line in text.splitlines():
        if line.startswith(BERKELEY_ORDER_COMMENT):
            names = [n.strip() for n in line[len(BERKELEY_ORDER_COMMENT) :].split(",")]
            return names if all(names) else None
        if line.strip() and not line.lstrip().startswith("#"):
            return None
    return None


def _berkeley_order(
    joint_order: Sequence[str] | None, profile: RobotProfile | None, what: str
) -> list[str] | None:
    if joint_order is not None:
        names = list(joint_order)
        if profile is not None:  # upstream names (left_hip_roll_joint) are accepted for the URDF names
            names = [profile.joint(n).name if n in profile.upstream_names else n for n in names]
        return names
    if profile is not None:
        return list(profile.joint_names)
    return None


def _berkeley_directions(
    order: Sequence[str], urdf: UrdfModel | None, profile: RobotProfile | None, source: str
) -> list[int]:
    """Directions by precedence: the URDF's ``direction`` param, else the profile's."""
    dirs = []
    lacking = []
    for name in order:
        if urdf is not None and not urdf.has_joint(name) and name not in urdf.joint_params:
            raise JointMismatchError(f"{source}: joint {name!r} is not in URDF {urdf.source}")
        d = urdf.direction(name) if urdf is not None else None
        if d is None and profile is not None:
            d = profile.direction(name)
        if d is None:
            lacking.append(name)
            continue
        dirs.append(d)
    if lacking:
        have = []
        if urdf is not None:
            have.append(f"URDF {urdf.source} has no <param name='direction'>")
        have.append(f"profile {profile.name} has none" if profile is not None else "no robot profile")
        raise UsageError(
            f"{source}: berkeley-offsets holds joint-frame offsets and needs each joint's direction; none for "
            f"{', '.join(lacking)} ({'; '.join(have)}); pass --robot NAME or a URDF with direction params"
        )
    return dirs


def _read_berkeley(
    path: Path,
    urdf: UrdfModel | None = None,
    joint_order: Sequence[str] | None = None,
    profile: RobotProfile | None = None,
    parsed_yaml: Any = None,
    **_: Any,
) -> CalibrationFile:
    source = str(path)
    text = read_text(path, "calibration file")  # also read for the joint-order comment
    data = parsed_yaml if parsed_yaml is not None else load_yaml(text, source)
    if not isinstance(data, Mapping) or "position_offsets" not in data:
        raise FileFormatError(f"{source}: expected a mapping with key position_offsets")
    extra = [str(k) for k in data if k != "position_offsets"]
    if extra:
        raise FileFormatError(f"{source}: unknown key {', '.join(extra)}; expected only position_offsets")
    raw = data["position_offsets"]
    if not isinstance(raw, Sequence) or isinstance(raw, str) or not raw:
        raise FileFormatError(f"{source}: position_offsets must be a non-empty list of numbers")
    offsets = [parse_finite(v, source, f"position_offsets[{i}]") for i, v in enumerate(raw)]
    written = _order_from_comment(text)
    if written is not None and len(written) != len(offsets):
        written = None  # a stale comment (the list was edited): not the file's order
    # --joints first, then the order the file names (robocal's own files), then the profile's
    order = (
        _berkeley_order(joint_order, profile, source) if joint_order is not None or written is None else None
    )
    notes: tuple[str, ...] = ()
    if order is None and written is None:
        raise UsageError(_no_order_message(source))
    if order is None and written is not None:
        order = written  # a file robocal wrote names its order; that is how its offsets are laid out
        if profile is None:
            profile = profile_for_joints(order)  # a known robot's joints give the directions
        elif list(profile.joint_names) != order and set(profile.joint_names) == set(order):
            notes = (
                f"{source}: its joints are in another order than robot {profile.name}'s low-level code reads "
                f"them ({', '.join(profile.joint_names)}); that code reads by index and would put offsets on "
                "other joints: rewrite it with --to berkeley-offsets (without --joints)",
            )
    elif written is not None and order is not None and written != order:
        raise JointMismatchError(
            f"{source}: the file says its joint order is {', '.join(written)}, but --joints gives "
            f"{', '.join(order)}; the offsets would land on other joints"
        )
    assert order is not None
    if len(order) != len(offsets):
        raise JointMismatchError(
            f"{source}: {len(offsets)} offsets but {len(order)} joints in the order ({', '.join(order)})"
        )
    dirs = _berkeley_directions(order, urdf, profile, source)
    h = homing_from_berkeley_offset(np.array(dirs, float), np.array(offsets))
    ids: dict[str, int] = {}
    for n in order:
        mid = urdf.motor_id(n) if urdf is not None else None
        if mid is None and profile is not None:
            mid = profile.motor_id(n)
        if mid is not None:
            ids[n] = int(mid)
    return CalibrationFile(
        RobotCalibration(order, dirs, h, 1.0), MappingProxyType(ids), "berkeley-offsets", source, notes
    )


def _write_berkeley(
    path: Path,
    cf: CalibrationFile,
    urdf: UrdfModel | None,
    joint_order: Sequence[str] | None = None,
    profile: RobotProfile | None = None,
    **_: Any,
) -> None:
    cal = cf.calibration
    if profile is None and joint_order is None:  # a calibration of exactly a known robot's joints
        profile = profile_for_joints(cal.joint_names)
    order = _berkeley_order(joint_order, profile, "berkeley-offsets")
    if order is None:
        raise UsageError(_no_order_message(f"cannot write {path}"))
    in_order = set(order)
    missing = [n for n in order if n not in cal]
    extra = [n for n in cal.joint_names if n not in in_order]
    if missing or extra:
        by = "--joints" if joint_order is not None else f"robot {profile.name}"  # type: ignore[union-attr]
        detail = "; ".join(
            f"{what}: {', '.join(names)}"
            for what, names in (("not in the calibration", missing), (f"not in {by}", extra))
            if names
        )
        raise JointMismatchError(
            f"berkeley-offsets is positional in the order of {by}, but the joints differ ({detail}); "
            "pass --joints for the order"
        )
    cal = cal.select(order)
    _require_rad(cal, "berkeley-offsets")
    offs = berkeley_offset_from_homing(cal.direction, cal.homing_offset)
    body = ", ".join(format_float(v) for v in offs)
    robot = f" (robot {profile.name})" if profile is not None and joint_order is None else ""
    text = (
        "# Berkeley-Humanoid-Lite-Lowlevel joint offsets (rad, joint frame): q = direction*raw - offset\n"
        f"{BERKELEY_ORDER_COMMENT}{', '.join(cal.joint_names)}\n"
        f"# read by index in this order{robot}\n"
        f"position_offsets: [{body}]\n"
    )
    atomic_write_text(path, text)


# ------------------------------------------------------------------------------------- ros2-transmission
_SIMPLE = "SimpleTransmission"


_REDUCTION_TAGS = ("mechanical_reduction", "mechanicalReduction")  # ros2_control, ROS 1


def _child_el(el: Any, *tags: str) -> Any:
    """The first child with one of ``tags`` and non-blank text, or None."""
    for tag in tags:
        c = el.find(tag)
        if c is not None and c.text is not None and c.text.strip():
            return c
    return None


def _child_text(el: Any, *tags: str) -> str | None:
    c = _child_el(el, *tags)
    return None if c is None else str(c.text.strip())


def _transmissions(root: Any) -> list[Any]:
    """``<transmission>`` elements under ``<robot>`` and inside ``<ros2_control>``, in document order."""
    found: list[Any] = []
    for el in root:
        if el.tag == "transmission":
            found.append(el)
        elif el.tag == "ros2_control":
            found.extend(el.findall("transmission"))
    return found


def _is_simple(tr: Any) -> bool:
    return (_child_text(tr, "plugin", "type") or "").endswith(_SIMPLE)


def _reduction_el(tr: Any, joint: Any) -> Any:
    """The element holding the reduction: the joint's (ros2_control) or else the actuator's (ROS 1 style)."""
    el = _child_el(joint, *_REDUCTION_TAGS)
    if el is None:
        actuator = tr.find("actuator")
        if actuator is not None:
            el = _child_el(actuator, *_REDUCTION_TAGS)
    return el


def _read_transmission(path: Path, **_: Any) -> CalibrationFile:
    source = str(path)
    tree = _parse_tree(read_bytes(path, "URDF"), source)
    root = tree.getroot()
    names, dirs, offs, scales = [], [], [], []
    seen: set[str] = set()
    skipped: list[str] = []
    for tr in _transmissions(root):
        tname = tr.get("name") or f"line {tr.sourceline}"
        if not _is_simple(tr):
            skipped.append(tname)
            continue
        joint = tr.find("joint")
        if joint is None or not joint.get("name"):
            raise FileFormatError(f"{source}: transmission {tname!r} has no <joint name=...>")
        jname = joint.get("name")
        where = f"{source}: transmission {tname!r} joint {jname!r}"
        red_el = _reduction_el(tr, joint)
        red_text = "1" if red_el is None else red_el.text.strip()
        reduction = parse_finite(red_text, where, "mechanical_reduction")
        if reduction == 0.0:
            raise FileFormatError(f"{where}: mechanical_reduction is 0")
        offset = parse_finite(_child_text(joint, "offset") or "0", where, "offset")
        if jname in seen:
            raise FileFormatError(f"{source}: joint {jname!r} has two transmissions")
        seen.add(jname)
        names.append(jname)
        dirs.append(1 if reduction > 0 else -1)
        scales.append(1.0 / abs(reduction))
        offs.append(-offset * reduction)
    if not names:
        raise FileFormatError(f"{source}: no SimpleTransmission <transmission> elements found")
    notes = (f"skipped non-SimpleTransmission transmissions: {', '.join(skipped)}",) if skipped else ()
    model_ids: dict[str, int] = {}
    try:
        model = _model_from_tree(tree, source)
        for n in names:
            mid = model.motor_id(n) if n in model.joint_params else None
            if mid is not None:
                model_ids[n] = mid
    except FileFormatError:
        pass
    return CalibrationFile(
        RobotCalibration(names, dirs, offs, scales),
        MappingProxyType(model_ids),
        "ros2-transmission",
        source,
        notes,
    )


def _same_number(el: Any, value: float) -> bool:
    """True when ``el`` already holds ``value`` (so an unchanged value keeps its spelling)."""
    try:
        return el is not None and float((el.text or "").strip()) == value
    except ValueError:
        return False


def _set_child(parent: Any, tag: str, value: float, indent: str) -> None:
    el = parent.find(tag)
    if _same_number(el, value) or (el is None and tag == "offset" and value == 0.0):
        return  # unchanged, or an absent <offset> that stays 0
    if el is None:
        el = etree.SubElement(parent, tag)
        children = list(parent)
        if len(children) >= 2:
            el.tail = children[-2].tail
            children[-2].tail = indent
        else:
            parent.text = indent
    el.text = format_float(value)


def _append_transmission(host: Any, joint: str, reduction: float, offset: float) -> None:
    text = host.text or ""
    indent = text.split("\n")[-1] if "\n" in text else "  "
    outer = (host.tail or "\n").split("\n")[-1] if host.getparent() is not None else ""
    xml = (
        f'<transmission name="{joint}_transmission">\n'
        f"{indent}  <plugin>transmission_interface/SimpleTransmission</plugin>\n"
        f'{indent}  <actuator name="{joint}_actuator" role="actuator1"/>\n'
        f'{indent}  <joint name="{joint}" role="joint1">\n'
        f"{indent}    <mechanical_reduction>{format_float(reduction)}</mechanical_reduction>\n"
        f"{indent}    <offset>{format_float(offset)}</offset>\n"
        f"{indent}  </joint>\n"
        f"{indent}</transmission>"
    )
    el = etree.fromstring(xml)
    try:
        last = host[-1]  # O(1) in lxml; list(host) and len(host) walk every child
    except IndexError:
        last = None
    if last is not None:
        el.tail = last.tail
        last.tail = "\n" + indent
        last.addnext(el)
    else:
        host.text = "\n" + indent
        el.tail = "\n" + outer
        host.append(el)


def _write_transmission(path: Path, cf: CalibrationFile, urdf: UrdfModel | None, **_: Any) -> None:
    cal = cf.calibration
    doc: UrdfDocument
    if path.exists():
        doc = UrdfDocument.load(path)
    elif urdf is not None and urdf.source and Path(urdf.source).is_file():
        doc = UrdfDocument.load(urdf.source)
    else:
        doc = UrdfDocument.from_bytes(
            b'<?xml version="1.0"?>\n<robot name="robocal_calibration">\n  <!-- SimpleTransmission calibration written by robocal -->\n</robot>\n'
        )
    root = doc.root()
    by_joint = {}
    for tr in _transmissions(root):
        j = tr.find("joint")
        if j is not None and j.get("name") and _is_simple(tr):
            by_joint[j.get("name")] = tr
    host_of: dict[str, Any] = {}  # the first <ros2_control> listing a joint hosts its new transmission
    for sys_el in root.findall("ros2_control"):
        for j in sys_el.findall("joint"):
            host_of.setdefault(j.get("name"), sys_el)
    for n, d, h, s in zip(cal.joint_names, cal.direction, cal.homing_offset, cal.scale, strict=True):
        reduction = float(d) / float(s)
        offset = -float(h) / reduction
        tr = by_joint.get(n)
        if tr is None:
            _append_transmission(host_of.get(n, root), n, reduction, offset)
        else:
            jel = tr.find("joint")
            indent = (jel.text or "\n        ") if jel is not None else "\n"
            red_el = _reduction_el(tr, jel)
            if red_el is None:
                _set_child(jel, "mechanical_reduction", reduction, indent)
            elif not _same_number(red_el, reduction):  # where it is (a ROS 1 file keeps it on the actuator)
                red_el.text = format_float(reduction)
            _set_child(jel, "offset", offset, indent)
    atomic_write_bytes(path, doc.to_bytes())


# -------------------------------------------------------------------------------------- lerobot-legacy
def _read_lerobot_legacy(path: Path, **_: Any) -> CalibrationFile:
    from ..core.lerobot.legacy import degree_joint_map
    from .lerobot import read_legacy  # lazy: only needed for this format

    cal = read_legacy(path)
    rc, linear = degree_joint_map(cal)  # DEGREE joints exactly; LINEAR ones are named and left out
    notes = (
        (f"{path}: LINEAR motor(s) {', '.join(linear)} left out (percent of a span, not a joint angle)",)
        if linear
        else ()
    )
    return CalibrationFile(rc, MappingProxyType({}), "lerobot-legacy", str(path), notes)


# ------------------------------------------------------------------------------------------- registry
Reader = Callable[..., CalibrationFile]
Writer = Callable[..., None]


@dataclass(frozen=True)
class FormatSpec:
    """One calibration file format."""

    name: str
    description: str
    reader: Reader
    writer: Writer | None


FORMATS: dict[str, FormatSpec] = {
    "lite-json": FormatSpec(
        "lite-json",
        "Lite-Lowlevel-Python calibration.json {joint: {id, direction, homing_offset}}",
        _read_lite_json,
        _write_lite_json,
    ),
    "lite-yaml": FormatSpec(
        "lite-yaml",
        "Humanoid-Control calibration.yaml (same schema; updated in place)",
        _read_lite_yaml,
        _write_lite_yaml,
    ),
    "berkeley-offsets": FormatSpec(
        "berkeley-offsets",
        "Berkeley-Humanoid-Lite-Lowlevel {position_offsets: [...]} (joint frame, positional)",
        _read_berkeley,
        _write_berkeley,
    ),
    "ros2-transmission": FormatSpec(
        "ros2-transmission",
        "URDF <transmission> SimpleTransmission (mechanical_reduction, offset)",
        _read_transmission,
        _write_transmission,
    ),
    "lerobot-legacy": FormatSpec(
        "lerobot-legacy", "LeRobot legacy array JSON (read only; DEGREE joints)", _read_lerobot_legacy, None
    ),
    "robocal": FormatSpec(
        "robocal",
        "robocal canonical joint map YAML (direction, homing_offset, scale)",
        _read_robocal,
        _write_robocal,
    ),
}


def _check_fmt(fmt: str) -> FormatSpec:
    if fmt not in FORMATS:
        raise UsageError(f"unknown format {fmt!r}; valid: {', '.join(FORMATS)}")
    return FORMATS[fmt]


def _sniff(text: str, source: str) -> tuple[str | None, Any]:
    """The format of ``text`` and, when it was parsed as YAML to tell, the YAML document (else None)."""
    stripped = text.lstrip("\ufeff \t\r\n")
    if stripped.startswith("<"):
        return "ros2-transmission", None
    if stripped.startswith("{") or stripped.startswith("["):
        try:
            data = json.loads(stripped)
        except (ValueError, RecursionError):  # reported by the real reader below
            data = None
        if isinstance(data, dict):
            if "position_offsets" in data:
                return "berkeley-offsets", None
            if "motor_names" in data and "homing_offset" in data:
                return "lerobot-legacy", None
            _refuse_motor_configuration(data, source)
            first = next(iter(data.values()), None)
            if isinstance(first, dict) and "range_min" in first:
                return "lerobot", None
            if isinstance(first, dict):
                return "lite-json", None
            return None, None
    try:
        data = load_yaml(text, source, item="joint")
    except FileFormatError:
        if stripped.startswith(("{", "[")):
            load_json(stripped, source)  # raises: report the JSON syntax error (line, column)
        raise  # a YAML syntax error is reported as such (line, column), not as an unknown format
    if isinstance(data, Mapping):
        if data.get("format") == ROBOCAL_FORMAT_TAG:
            return "robocal", data
        if "position_offsets" in data:
            return "berkeley-offsets", data
        first = next(iter(data.values()), None)
        if isinstance(first, Mapping):
            return "lite-yaml", data
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
    text = read_text(path, "calibration file")
    fmt, data = _sniff(text, source)
    if fmt == "lerobot":
        raise FileFormatError(
            f"{source}: a current LeRobot calibration (range_min/range_max) is not a joint map; "
            "use 'robocal lerobot export-urdf' to derive one"
        )
    if fmt is None:
        raise FileFormatError(
            f"{source}: unrecognised calibration format (known: {', '.join(FORMATS)}); "
            "name it explicitly if it is one of them (robocal convert --from)"
        )
    return fmt, data


def _format_for_output(path: Path) -> str:
    if os.path.exists(path) and os.path.getsize(path) > 0:
        try:
            fmt = detect_format(path)
            if FORMATS[fmt].writer is not None:
                return fmt
        except FileFormatError:
            pass
    suffix = path.suffix.lower()
    if suffix == ".json":
        return "lite-json"
    if suffix in (".yaml", ".yml"):
        return "lite-yaml"
    if suffix in (".urdf", ".xml"):
        return "ros2-transmission"
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
        cf = CalibrationFile(cf.calibration, {**cf.ids, **ids}, cf.fmt, cf.source, cf.notes)
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


_SELF_CONTAINED = ("lite-json", "lite-yaml", "robocal")


def read_existing_output(
    path: str | os.PathLike[str],
    fmt: str,
    what: str = "destination",
    *,
    urdf: UrdfModel | None = None,
    joint_order: Sequence[str] | None = None,
    robot: str | os.PathLike[str] | RobotProfile | None = None,
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

    Returns:
        The calibration the file holds (for the self-contained formats), else None.

    Raises:
        FileFormatError: The file holds something else; nothing is written. The message says what it looks
            like and to move it away or choose another destination.
    """
    p = Path(path)
    if not os.path.exists(p):  # os.path: a name too long is "missing" here and refused by the writer
        return None
    text = read_text(p, what)
    if all(not ln.strip() or ln.lstrip().startswith("#") for ln in text.splitlines()):
        return None  # empty, or only comments: nothing to keep

    def refuse(why: str) -> FileFormatError:
        return FileFormatError(
            f"{what} {p}: exists but is not a {fmt} calibration file ({why}); move it away or choose another "
            f"{'--out' if what == '--out' else 'destination'}"
        )

    try:
        found, _doc = _sniff(text, str(p))
    except FileFormatError as exc:
        raise refuse(str(exc)) from None
    if found != fmt:
        raise refuse(f"it looks like {found}" if found else "not a calibration format robocal knows")
    if fmt not in _SELF_CONTAINED:
        return None
    try:
        return read_calibration(p, fmt, urdf=urdf, joint_order=joint_order, robot=robot)
    except CalibError as exc:
        raise refuse(str(exc)) from None
