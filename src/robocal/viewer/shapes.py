"""Give a URDF simple-shape visuals (cylinders and spheres) so it can be viewed without mesh files.

:func:`add_simple_shapes` adds to every link a sphere at its origin and a cylinder to each child joint's
origin, and (``replace_meshes=True``) removes ``<visual>`` elements that point at mesh files. The robot's
joints, limits, ``<ros2_control>`` and comments are untouched. robocal ships the Lite example and the
simulated SO-101 made this way (``robocal/data/lite_bimanual_shapes.urdf``, ``so101_shapes.urdf``).
"""

from __future__ import annotations

import math

import numpy as np
from lxml import etree

from ..formats.urdf import parse_urdf

__all__ = ["add_simple_shapes"]

ROD_RADIUS_M = 0.015
BALL_RADIUS_M = 0.025
"""Sizes of the simple-shape visuals written into a URDF (cylinder per joint, sphere per link)."""


def _rpy_z_to(d: np.ndarray) -> tuple[float, float, float]:
    """URDF rpy of a rotation taking +z to the unit vector ``d``."""
    z = np.array([0.0, 0.0, 1.0])
    axis = np.cross(z, d)
    s = float(np.linalg.norm(axis))
    c = float(np.dot(z, d))
    if s < 1e-12:
        return (0.0, 0.0, 0.0) if c > 0 else (math.pi, 0.0, 0.0)
    k = axis / s
    K = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
    R = np.eye(3) + s * K + (1 - c) * K @ K
    roll = math.atan2(R[2, 1], R[2, 2])
    pitch = -math.asin(max(-1.0, min(1.0, R[2, 0])))
    yaw = math.atan2(R[1, 0], R[0, 0])
    return roll, pitch, yaw


def _f(x: float) -> str:
    text = f"{x:.6f}".rstrip("0").rstrip(".")
    return "0" if text in ("-0", "") else text


def add_simple_shapes(
    urdf_text: str, *, replace_meshes: bool = True, rgba: str = "0.42 0.48 0.58 1", comment: str = ""
) -> str:
    """The URDF with a sphere per link and a cylinder from each link to each child joint.

    Args:
        urdf_text: The URDF.
        replace_meshes: Remove ``<visual>`` elements whose geometry is a ``<mesh>``.
        rgba: Colour of the added shapes.
        comment: Written as an XML comment before ``<robot>`` (the original's prolog comments are not kept).

    Returns:
        The new URDF text.

    Raises:
        FileFormatError: The URDF does not parse.
    """
    model = parse_urdf(urdf_text)
    parser = etree.XMLParser(resolve_entities=False, no_network=True, remove_blank_text=False)
    root = etree.fromstring(urdf_text.encode(), parser)
    links = {el.get("name"): el for el in root.findall("link")}
    children: dict[str, list[tuple[float, float, float]]] = {}
    for j in model.joints:
        children.setdefault(j.parent, []).append(j.origin_xyz_m)
    for name, el in links.items():
        if replace_meshes:
            for vis in el.findall("visual"):
                if vis.find("geometry/mesh") is not None:
                    el.remove(vis)
        shapes = [
            (
                "sphere",
                {"radius": _f(BALL_RADIUS_M)},
                (0.0, 0.0, 0.0),
                (0.0, 0.0, 0.0),
            )
        ]
        for xyz in children.get(name, []):
            d = np.array(xyz, dtype=np.float64)
            length = float(np.linalg.norm(d))
            if length < 1e-4:
                continue
            mid = tuple(float(v) for v in d / 2)
            shapes.append(
                (
                    "cylinder",
                    {"radius": _f(ROD_RADIUS_M), "length": _f(length)},
                    mid,  # type: ignore[arg-type]
                    _rpy_z_to(d / length),
                )
            )
        indent = "\n    "
        if el.text is None or not el.text.strip():
            el.text = indent
        for kind, attrs, xyz3, rpy in shapes:
            vis = etree.SubElement(el, "visual")
            vis.text = indent + "  "
            origin = etree.SubElement(vis, "origin", xyz=" ".join(map(_f, xyz3)), rpy=" ".join(map(_f, rpy)))
            origin.tail = indent + "  "
            geometry = etree.SubElement(vis, "geometry")
            etree.SubElement(geometry, kind, **attrs)
            geometry.tail = indent + "  "
            material = etree.SubElement(vis, "material", name="robocal_simple")
            etree.SubElement(material, "color", rgba=rgba)
            material.tail = indent
            vis.tail = indent
        last = el[-1] if len(el) else None
        if last is not None:
            last.tail = "\n  "
    text: str = etree.tostring(root, encoding="unicode")
    head = f"<!-- {comment.replace('--', '-')} -->\n" if comment else ""
    return '<?xml version="1.0"?>\n' + head + text + "\n"
