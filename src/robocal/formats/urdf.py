"""URDF reading and in-place editing with lxml.

Robot joints are the ``<joint>`` elements that are **direct children** of ``<robot>``; ``<ros2_control>`` reuses
the tag ``joint`` for its own entries, which are read separately as string parameters. Parsing never expands
entities and never touches the network; a document that declares entities is refused. Editing changes
attribute values in place, so comments, element order, ``<ros2_control>``, ``<gazebo>`` and formatting survive.
"""

from __future__ import annotations

import os
from collections.abc import Iterator, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from types import MappingProxyType
from typing import Any

from lxml import etree

from ..core.arrays import Vec3
from ..core.chain import URDF_JOINT_TYPES, ChainJoint
from ..errors import FileFormatError, JointMismatchError, UsageError
from ..fileio import MAX_URDF_BYTES, atomic_write_bytes, read_bytes
from ._numbers import format_float, parse_finite

__all__ = [
    "UrdfDocument",
    "UrdfModel",
    "parse_urdf",
    "parse_vec3",
    "read_urdf",
]

XACRO_NS = "http://www.ros.org/wiki/xacro"
_LIMIT_ATTRS = ("lower", "upper", "velocity", "effort")


@dataclass(frozen=True)
class UrdfModel:
    """The parts of a URDF robocal uses.

    Attributes:
        name: ``<robot name>``.
        joints: Robot joints in document order.
        joint_params: ``<ros2_control>/<joint>`` parameters, ``{joint: {param: text}}`` (strings, stripped),
            merged over every ``<ros2_control>`` system in document order.
        hardware_params: ``<ros2_control>/<hardware>/<param>`` per system name.
        source: Where the URDF was read from.
    """

    name: str
    joints: tuple[ChainJoint, ...]
    joint_params: Mapping[str, Mapping[str, str]] = field(default_factory=dict)
    hardware_params: Mapping[str, Mapping[str, str]] = field(default_factory=dict)
    source: str = "<string>"
    _by_name: Mapping[str, ChainJoint] = field(init=False, repr=False, compare=False)

    @property
    def joint_names(self) -> tuple[str, ...]:
        """Names of all robot joints in document order."""
        return tuple(j.name for j in self.joints)

    @property
    def movable_joint_names(self) -> tuple[str, ...]:
        """Names of the non-fixed joints in document order."""
        return tuple(j.name for j in self.joints if j.is_movable)

    @property
    def ros2_control_joint_names(self) -> tuple[str, ...]:
        """Joints listed in ``<ros2_control>`` blocks, in document order."""
        return tuple(self.joint_params)

    def __post_init__(self) -> None:
        object.__setattr__(self, "_by_name", {j.name: j for j in self.joints})

    def has_joint(self, name: str) -> bool:
        """True when the URDF has a robot joint called ``name`` (O(1))."""
        return name in self._by_name

    def joint(self, name: str) -> ChainJoint:
        """The joint called ``name`` (O(1)); :class:`JointMismatchError` listing the valid names if absent."""
        j = self._by_name.get(name)
        if j is not None:
            return j
        raise JointMismatchError(
            f"URDF {self.source}: no joint {name!r}; joints: {', '.join(self.joint_names)}"
        )

    def param(self, joint: str, name: str) -> str | None:
        """A ``<ros2_control>`` joint parameter as text, or None."""
        return self.joint_params.get(joint, {}).get(name)

    def calibration_joint_names(self) -> tuple[str, ...]:
        """The joint order for calibration files.

        The ``<ros2_control>`` joints if there are any, else the movable joints that have their own motor
        (mimic joints follow another joint and are left out).
        """
        return self.ros2_control_joint_names or tuple(
            j.name for j in self.joints if j.is_movable and j.mimic is None
        )

    def direction(self, joint: str) -> int | None:
        """The ``direction`` parameter of a joint (±1), None when absent; bad values raise FileFormatError."""
        from ._numbers import parse_direction

        text = self.param(joint, "direction")
        if text is None:
            return None
        return parse_direction(text, f"URDF {self.source}: joint {joint!r} <param name='direction'>")

    def motor_id(self, joint: str) -> int | None:
        """The motor id of a joint from its ``id`` or ``can_id`` parameter, None when absent."""
        from ._numbers import parse_motor_id

        for key in ("id", "can_id", "motor_id"):
            text = self.param(joint, key)
            if text is not None:
                return parse_motor_id(text, f"URDF {self.source}: joint {joint!r}", f"<param name='{key}'>")
        return None

    def limits(self, joint: str) -> tuple[float, float]:
        """``(lower, upper)`` of a joint, from ``<limit>`` or the ``lower_limit``/``upper_limit`` params."""
        j = self.joint(joint)
        lo, up = j.lower, j.upper
        where = f"URDF {self.source}: joint {joint!r}"
        if lo is None and self.param(joint, "lower_limit") is not None:
            lo = parse_finite(self.param(joint, "lower_limit"), where, "<param name='lower_limit'>")
        if up is None and self.param(joint, "upper_limit") is not None:
            up = parse_finite(self.param(joint, "upper_limit"), where, "<param name='upper_limit'>")
        if lo is None or up is None:
            raise FileFormatError(f"{where}: has no lower/upper limit")
        if lo > up:
            raise FileFormatError(f"{where}: lower limit {lo} is above upper limit {up}")
        return lo, up


def _parser() -> etree.XMLParser:
    return etree.XMLParser(
        resolve_entities=False,
        no_network=True,
        load_dtd=False,
        dtd_validation=False,
        huge_tree=False,
        remove_blank_text=False,
        remove_comments=False,
    )


def _parse_tree(data: bytes, source: str) -> Any:
    try:
        root = etree.fromstring(data, _parser())
    except etree.XMLSyntaxError as exc:
        line = getattr(exc, "lineno", None)
        where = f" (line {line})" if line else ""
        raise FileFormatError(f"URDF {source}: not well-formed XML{where}: {exc.msg}") from None
    tree = root.getroottree()
    dtd = tree.docinfo.internalDTD
    if dtd is not None and any(True for _ in dtd.iterentities()):
        raise FileFormatError(
            f"URDF {source}: entity declarations are not allowed (possible XXE); expand it first"
        )
    for el in root.iter():
        if isinstance(el, etree._Entity):
            raise FileFormatError(f"URDF {source}: unresolved entity reference &{el.name}; is not allowed")
    if root.tag != "robot":
        raise FileFormatError(f"URDF {source}: root element is <{root.tag}>, expected <robot>")
    if any(ns == XACRO_NS for ns in root.nsmap.values()) or any(
        "${" in value for el in root.iter(tag=etree.Element) for value in el.attrib.values()
    ):
        raise FileFormatError(
            f"URDF {source}: this is a xacro file (xacro namespace or ${{...}} expressions); "
            "expand it first: xacro robot.urdf.xacro > robot.urdf"
        )
    return tree


def parse_vec3(text: str | None, default: Vec3, where: str, attr: str) -> Vec3:
    """A URDF ``xyz``/``rpy`` attribute: three finite numbers, or ``default`` when it is absent.

    Raises:
        FileFormatError: Not three numbers, or one that is NaN, inf or not a number (``where`` and ``attr`` name it).
    """
    if text is None:
        return default
    parts = text.split()
    if len(parts) != 3:
        raise FileFormatError(f"{where}: {attr}={text!r} must have 3 numbers")
    x, y, z = (parse_finite(p, where, attr) for p in parts)
    return (x, y, z)


def _opt_float(el: Any, attr: str, where: str) -> float | None:
    text = el.get(attr)
    return None if text is None else parse_finite(text, where, f"<limit {attr}>")


def named_elements(root: Any, tag: str, source: str, no_name: str) -> Iterator[tuple[str, Any]]:
    """``(name, element)`` of each ``<tag>`` child of ``root`` in document order.

    Args:
        root: The parsed ``<robot>`` element.
        tag: ``joint`` or ``link``.
        source: File name for messages.
        no_name: The message for an element without a name; ``{where}`` is ``URDF <source>: <tag> on line N``.

    Raises:
        FileFormatError: An element without a name, or two with the same name.
    """
    seen: set[str] = set()
    for el in root.findall(tag):
        name = el.get("name")
        if not name:
            raise FileFormatError(no_name.format(where=f"URDF {source}: <{tag}> on line {el.sourceline}"))
        if name in seen:
            raise FileFormatError(f"URDF {source}: duplicate {tag} {name!r}")
        seen.add(name)
        yield name, el


def _model_from_tree(tree: Any, source: str) -> UrdfModel:
    root = tree.getroot()
    joints: list[ChainJoint] = []
    for name, el in named_elements(root, "joint", source, "{where}: missing name attribute"):
        where = f"URDF {source}: joint {name!r}"
        jtype = el.get("type")
        if jtype not in URDF_JOINT_TYPES:
            raise FileFormatError(f"{where}: type {jtype!r} is not a URDF joint type")
        parent, child = el.find("parent"), el.find("child")
        if parent is None or child is None or not parent.get("link") or not child.get("link"):
            raise FileFormatError(f"{where}: needs <parent link=...> and <child link=...>")
        origin = el.find("origin")
        xyz = parse_vec3(origin.get("xyz") if origin is not None else None, (0.0, 0.0, 0.0), where, "origin xyz")
        rpy = parse_vec3(origin.get("rpy") if origin is not None else None, (0.0, 0.0, 0.0), where, "origin rpy")
        axis_el = el.find("axis")
        axis = parse_vec3(axis_el.get("xyz") if axis_el is not None else None, (1.0, 0.0, 0.0), where, "axis xyz")
        lim = el.find("limit")
        lower, upper, velocity, effort = (None if lim is None else _opt_float(lim, a, where) for a in _LIMIT_ATTRS)
        if lower is not None and upper is not None and lower > upper:
            raise FileFormatError(f"{where}: limit lower {lower} is above upper {upper}")
        mimic_el = el.find("mimic")
        joints.append(
            ChainJoint(
                name=name,
                type=jtype,
                parent=parent.get("link"),
                child=child.get("link"),
                origin_xyz_m=xyz,
                origin_rpy_rad=rpy,
                axis=axis,
                lower=lower,
                upper=upper,
                velocity=velocity,
                effort=effort,
                mimic=mimic_el.get("joint") if mimic_el is not None else None,
            )
        )
    joint_params: dict[str, dict[str, str]] = {}
    hardware_params: dict[str, dict[str, str]] = {}
    for sys_el in root.findall("ros2_control"):
        sys_name = sys_el.get("name") or f"system{len(hardware_params)}"
        hw = sys_el.find("hardware")
        hardware_params[sys_name] = {
            p.get("name"): (p.text or "").strip() for p in (hw.findall("param") if hw is not None else [])
        }
        for jel in sys_el.findall("joint"):
            jname = jel.get("name")
            if not jname:
                raise FileFormatError(
                    f"URDF {source}: <ros2_control> joint on line {jel.sourceline} has no name"
                )
            params = joint_params.setdefault(jname, {})
            for p in jel.findall("param"):
                pname = p.get("name")
                if pname:
                    params[pname] = (p.text or "").strip()
    return UrdfModel(
        name=root.get("name") or "",
        joints=tuple(joints),
        joint_params=MappingProxyType({k: MappingProxyType(v) for k, v in joint_params.items()}),
        hardware_params=MappingProxyType({k: MappingProxyType(v) for k, v in hardware_params.items()}),
        source=source,
    )


def parse_urdf(data: bytes | str, source: str = "<string>") -> UrdfModel:
    """Parse URDF text or bytes into a :class:`UrdfModel`.

    Raises:
        FileFormatError: Not well-formed, entity declarations, not a ``<robot>``, bad numbers, duplicates.
    """
    raw = data.encode("utf-8") if isinstance(data, str) else data
    return _model_from_tree(_parse_tree(raw, source), source)


def read_urdf(path: str | os.PathLike[str]) -> UrdfModel:
    """Read a URDF file (an expanded URDF, not xacro) into a :class:`UrdfModel`."""
    return parse_urdf(read_bytes(path, "URDF", limit=MAX_URDF_BYTES), str(path))


def _prolog_epilog(original: bytes, tree: Any) -> tuple[bytes | None, bytes | None]:
    """Bytes before the root start tag and after its end tag, so re-serialising keeps them verbatim."""
    root = tree.getroot()
    line = root.sourceline or 1
    lines = original.splitlines(keepends=True)
    offset = sum(len(x) for x in lines[: line - 1])
    start = original.find(b"<" + root.tag.encode(), offset)
    end = original.rfind(b"</" + root.tag.encode())
    if start < 0:
        return None, None
    if end < 0:  # self-closing root
        end_tag = original.rfind(b"/>")
        return original[:start], original[end_tag + 2 :] if end_tag > start else b"\n"
    close = original.find(b">", end)
    return original[:start], original[close + 1 :] if close >= 0 else b"\n"


def _triple(old: str | None, values: Sequence[float]) -> str:
    """``values`` as an ``xyz``/``rpy`` attribute, keeping each of ``old``'s numbers that has the same value."""
    tokens = (old or "").split()
    if len(tokens) != len(values):
        return " ".join(format_float(v) for v in values)
    out = [t if _number(t) == v else format_float(v) for t, v in zip(tokens, values, strict=True)]
    return old if old is not None and out == tokens else " ".join(out)


def _number(text: str) -> float | None:
    try:
        return float(text)
    except ValueError:
        return None


class UrdfDocument:
    """A URDF kept as an lxml tree for lossless in-place edits.

    Example:
        >>> doc = UrdfDocument.load("robot.urdf")  # doctest: +SKIP
        >>> doc.set_origin("elbow_joint", (0.1, 0.0, 0.0), (0.0, 0.0, 0.0))  # doctest: +SKIP
        >>> doc.write("robot_calibrated.urdf")  # doctest: +SKIP
    """

    def __init__(self, tree: Any, source: str, original: bytes | None = None) -> None:
        self._tree = tree
        self.source = source
        self._prolog, self._epilog = _prolog_epilog(original, tree) if original is not None else (None, None)

    @classmethod
    def load(cls, path: str | os.PathLike[str]) -> UrdfDocument:
        """Parse a URDF file for editing (same safety rules as :func:`read_urdf`)."""
        data = read_bytes(path, "URDF", limit=MAX_URDF_BYTES)
        tree = _parse_tree(data, str(path))
        _model_from_tree(tree, str(path))  # validate once up front
        return cls(tree, str(path), data)

    @classmethod
    def from_bytes(cls, data: bytes | str, source: str = "<string>") -> UrdfDocument:
        """Parse URDF text for editing."""
        raw = data.encode("utf-8") if isinstance(data, str) else data
        tree = _parse_tree(raw, source)
        _model_from_tree(tree, source)
        return cls(tree, source, raw)

    def model(self) -> UrdfModel:
        """The current state of the document as a :class:`UrdfModel`."""
        return _model_from_tree(self._tree, self.source)

    def _joint_el(self, joint: str) -> Any:
        # a name → element table built once (O(1) per lookup, so editing every joint stays linear); checked on
        # use and rebuilt when the tree was changed through root()
        root = self._tree.getroot()
        table: dict[str, Any] | None = getattr(self, "_joint_els", None)
        el = table.get(joint) if table is not None else None
        if el is not None and el.getparent() is root and el.get("name") == joint:
            return el
        table = {}
        for e in root.findall("joint"):
            table.setdefault(e.get("name"), e)
        self._joint_els = table
        if joint in table:
            return table[joint]
        names = [el.get("name") for el in self._tree.getroot().findall("joint")]
        raise JointMismatchError(
            f"URDF {self.source}: no joint {joint!r}; joints: {', '.join(map(str, names))}"
        )

    def set_origin(self, joint: str, xyz: Sequence[float], rpy: Sequence[float]) -> None:
        """Set a joint's ``<origin xyz rpy>`` (creating ``<origin>`` if absent), shortest round-trip floats.

        A number whose value stays keeps its text (``0`` stays ``0``): unchanged attributes stay byte for byte.

        Args:
            joint: Robot joint name.
            xyz: Translation, 3 floats, m.
            rpy: URDF roll, pitch, yaw, 3 floats, rad (``R = Rz(yaw)·Ry(pitch)·Rx(roll)``).
        """
        if len(xyz) != 3 or len(rpy) != 3:
            raise UsageError(f"set_origin({joint!r}): xyz and rpy need 3 values each")
        values = [float(v) for v in (*xyz, *rpy)]
        if any(v != v or v in (float("inf"), float("-inf")) for v in values):
            raise UsageError(f"set_origin({joint!r}): values must be finite, got {values}")
        el = self._joint_el(joint)
        origin = el.find("origin")
        if origin is None:
            origin = etree.Element("origin")
            parent = el.find("parent")
            idx = list(el).index(parent) if parent is not None else 0
            origin.tail = el.text
            el.insert(idx, origin)
        origin.set("xyz", _triple(origin.get("xyz"), values[:3]))
        origin.set("rpy", _triple(origin.get("rpy"), values[3:]))

    def set_param(self, joint: str, name: str, value: str) -> None:
        """Set a ``<ros2_control>/<joint>/<param name=...>`` text; the ``<ros2_control>`` joint must exist.

        An absent ``<param>`` is appended after the joint's last child.
        """
        found = False
        for sys_el in self._tree.getroot().findall("ros2_control"):
            for jel in sys_el.findall("joint"):
                if jel.get("name") != joint:
                    continue
                found = True
                for p in jel.findall("param"):
                    if p.get("name") == name:
                        p.text = value
                        break
                else:
                    p = etree.Element("param", name=name)
                    p.text = value
                    children = list(jel)
                    if children:
                        last = children[-1]
                        p.tail = last.tail
                        last.tail = children[-2].tail if len(children) >= 2 else jel.text
                        last.addnext(p)
                    else:
                        jel.append(p)
        if not found:
            raise JointMismatchError(
                f"URDF {self.source}: joint {joint!r} is not in any <ros2_control> block"
            )

    def root(self) -> Any:
        """The lxml root element, for edits not covered above (e.g. ``<transmission>`` blocks)."""
        return self._tree.getroot()

    def to_bytes(self) -> bytes:
        """Serialise keeping the original prolog (declaration, comments), comments and element order."""
        if self._prolog is not None and self._epilog is not None:
            body: bytes = etree.tostring(self._tree.getroot(), encoding="utf-8", xml_declaration=False)
            return self._prolog + body + self._epilog
        out: bytes = etree.tostring(self._tree, xml_declaration=True, encoding="utf-8")
        return out if out.endswith(b"\n") else out + b"\n"

    def write(self, path: str | os.PathLike[str]) -> Path:
        """Write atomically (keeping ``NAME.bak`` of an existing file)."""
        return atomic_write_bytes(path, self.to_bytes())
