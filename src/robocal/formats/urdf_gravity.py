"""A URDF's gravity model: its kinematic tree and the ``<inertial>`` mass and centre of mass of each link.

:func:`gravity_model_from_urdf` reads a URDF (the same safe lxml parse as :mod:`robocal.formats.urdf`) into a
:class:`~robocal.core.gravity.GravityModel`. Only ``<inertial><mass value>`` and ``<inertial><origin xyz>`` matter
for gravity (the inertia tensor and the inertial ``rpy`` do not). A ``mimic`` joint is taken as fixed at 0 (a
gripper's second jaw: its weight still counts, on the joints above it); floating and planar joints are refused.
"""

from __future__ import annotations

import os
from collections.abc import Sequence

from ..core.chain import ChainJoint
from ..core.gravity import STANDARD_GRAVITY_M_S2, GravityModel, LinkInertial
from ..errors import FileFormatError, JointMismatchError
from ._numbers import parse_finite
from .urdf import UrdfDocument, named_elements, parse_vec3
from .urdf_chain import root_link

__all__ = ["gravity_model_from_urdf", "gravity_model_if_any", "link_inertials"]


def link_inertials(doc: UrdfDocument) -> tuple[LinkInertial, ...]:
    """Mass and centre of mass of every ``<link>`` with an ``<inertial>``, in document order.

    Raises:
        FileFormatError: An ``<inertial>`` without ``<mass value>``, a negative, NaN or non-numeric mass or
            centre of mass, or two links with the same name.
    """
    out: list[LinkInertial] = []
    for name, el in named_elements(doc.root(), "link", doc.source, "{where} has no name"):
        inertial = el.find("inertial")
        if inertial is None:
            continue
        where = f"URDF {doc.source}: link {name!r} <inertial>"
        mass_el = inertial.find("mass")
        if mass_el is None or mass_el.get("value") is None:
            raise FileFormatError(f"{where}: needs <mass value=...>")
        mass = parse_finite(mass_el.get("value"), where, "<mass value>")
        if mass < 0:
            raise FileFormatError(f"{where}: mass {mass} is negative")
        origin = inertial.find("origin")
        com = parse_vec3(origin.get("xyz") if origin is not None else None, (0.0, 0.0, 0.0), where, "<origin xyz>")
        out.append(LinkInertial(name, mass, com))
    return tuple(out)


def _tree_joint(j: ChainJoint, source: str) -> ChainJoint:
    if j.type in ("floating", "planar"):
        raise JointMismatchError(
            f"URDF {source}: joint {j.name!r} is {j.type}; a gravity model cannot have it"
        )
    kind = "revolute" if j.type == "continuous" else j.type
    if j.mimic is not None:
        kind = "fixed"  # held at 0: its links still weigh on the joints above
    axis = j.axis if any(j.axis) else (0.0, 0.0, 1.0)
    if kind != "fixed" and not any(j.axis):
        raise JointMismatchError(f"URDF {source}: joint {j.name!r} has a zero axis")
    limited = kind != "fixed" and j.type != "continuous"
    lower, upper = (j.lower, j.upper) if limited else (None, None)
    return ChainJoint(j.name, kind, j.parent, j.child, j.origin_xyz_m, j.origin_rpy_rad, axis, lower, upper)


def gravity_model_from_urdf(
    source: UrdfDocument | str | os.PathLike[str],
    gravity_m_s2: Sequence[float] = STANDARD_GRAVITY_M_S2,
) -> GravityModel:
    """The gravity model of a URDF file (or a loaded document).

    Args:
        source: A URDF path or a :class:`~robocal.formats.urdf.UrdfDocument`.
        gravity_m_s2: Gravity in the root link's frame (default: upright, z up).

    Raises:
        FileFormatError: The file is not a valid URDF, or an ``<inertial>`` is malformed, or it has no link
            with a positive mass (nothing to model).
        JointMismatchError: The tree has no single root, or a floating/planar joint.
    """
    doc = source if isinstance(source, UrdfDocument) else UrdfDocument.load(source)
    model = doc.model()
    inertials = link_inertials(doc)
    if not any(i.mass_kg > 0 for i in inertials):
        raise FileFormatError(
            f"URDF {doc.source}: no link has an <inertial> with a positive mass; a gravity model needs the masses"
        )
    joints = tuple(_tree_joint(j, doc.source) for j in model.joints)
    root = root_link(model) if model.joints else inertials[0].link
    links = {root} | {j.child for j in joints}
    stray = [i.link for i in inertials if i.link not in links]
    if stray:
        raise JointMismatchError(
            f"URDF {doc.source}: link(s) {', '.join(stray)} are not connected to {root!r}"
        )
    g = tuple(float(v) for v in gravity_m_s2)
    return GravityModel(joints, inertials, root, (g[0], g[1], g[2]))


def gravity_model_if_any(source: UrdfDocument | str | os.PathLike[str]) -> GravityModel | None:
    """The URDF's gravity model when it has masses, None when no link has a positive ``<inertial>`` mass.

    Raises:
        FileFormatError: A malformed ``<inertial>`` (a URDF with masses must have valid ones).
        JointMismatchError: As :func:`gravity_model_from_urdf`.
    """
    doc = source if isinstance(source, UrdfDocument) else UrdfDocument.load(source)
    if not any(i.mass_kg > 0 for i in link_inertials(doc)):
        return None
    return gravity_model_from_urdf(doc)
