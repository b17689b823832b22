"""``ros2-transmission``: URDF ``<transmission>`` with ``SimpleTransmission`` (``mechanical_reduction``, ``offset``).

Transmissions are read under ``<robot>`` and inside ``<ros2_control>``; the reduction sits on the joint
(ros2_control) or on the actuator (ROS 1). Writing updates an existing URDF in place.
"""

from __future__ import annotations

from pathlib import Path
from types import MappingProxyType
from typing import Any

from lxml import etree

from ...core.jointmap import RobotCalibration
from ...errors import FileFormatError
from ...fileio import MAX_URDF_BYTES, atomic_write_bytes, read_bytes
from .._numbers import format_float, parse_finite
from ..urdf import UrdfDocument, UrdfModel, _model_from_tree, _parse_tree
from ._base import CalibrationFile, Content, FormatSpec, Traits

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


def read(path: Path, **_: Any) -> CalibrationFile:
    """Read the ``SimpleTransmission`` elements of a URDF (other transmissions are skipped with a note)."""
    source = str(path)
    tree = _parse_tree(read_bytes(path, "URDF", limit=MAX_URDF_BYTES), source)
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


def write(path: Path, cf: CalibrationFile, urdf: UrdfModel | None, **_: Any) -> None:
    """Update (or add) a ``SimpleTransmission`` per joint in the destination URDF, else in ``urdf``'s file."""
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


def sniff(content: Content) -> bool:
    """XML (a file starting with ``<``)."""
    return content.kind == "xml"


SPEC = FormatSpec("ros2-transmission", read, write, sniff, 1, (".urdf", ".xml"), Traits.DIRECTIONS)
