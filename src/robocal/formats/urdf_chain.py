"""Serial chains out of a URDF, and corrected chains back into it.

:func:`chain_from_urdf` follows the joints between two links of a parsed URDF (:mod:`robocal.formats.urdf`)
and returns a :class:`~robocal.core.chain.SerialChain`. :func:`corrected_urdf_bytes` writes a corrected
chain's joint origins into the original document in place: only the ``<origin>`` attributes of the chain's
movable joints change; comments, meshes, limits, ``<ros2_control>`` and everything else stay as they were.
"""

from __future__ import annotations

import math
from collections.abc import Mapping

from ..core.chain import ChainJoint, SerialChain
from ..errors import JointMismatchError, UsageError
from .urdf import UrdfDocument, UrdfModel

__all__ = ["chain_from_urdf", "corrected_urdf_bytes", "root_link", "tip_links"]


def root_link(model: UrdfModel) -> str:
    """The link that is nobody's child (the URDF root); :class:`JointMismatchError` if not exactly one."""
    parents = {j.parent for j in model.joints}
    children = {j.child for j in model.joints}
    roots = sorted(parents - children)
    if len(roots) != 1:
        raise JointMismatchError(
            f"URDF {model.source}: expected one root link, found {', '.join(roots) or 'none'}"
        )
    return roots[0]


def tip_links(model: UrdfModel) -> tuple[str, ...]:
    """Links that are no joint's parent (the leaves), in document order."""
    parents = {j.parent for j in model.joints}
    return tuple(j.child for j in model.joints if j.child not in parents)


def _chain_joint(j: ChainJoint, source: str) -> ChainJoint:
    if j.type in ("floating", "planar"):
        raise JointMismatchError(
            f"URDF {source}: joint {j.name!r} is {j.type}; a serial chain cannot have it"
        )
    if j.mimic is not None:
        raise JointMismatchError(
            f"URDF {source}: joint {j.name!r} mimics {j.mimic!r}; pick a chain without mimic joints"
        )
    kind = "revolute" if j.type == "continuous" else j.type
    lower = upper = None
    if j.type != "continuous":
        lower, upper = j.lower, j.upper
    axis = j.axis
    if kind == "fixed" and not any(axis):
        axis = (0.0, 0.0, 1.0)  # URDFs often write axis="0 0 0" on fixed joints; it is never used
    if kind != "fixed" and math.sqrt(sum(a * a for a in axis)) < 1e-12:
        raise JointMismatchError(f"URDF {source}: joint {j.name!r} has a zero axis")
    return ChainJoint(
        name=j.name,
        type=kind,
        parent=j.parent,
        child=j.child,
        origin_xyz_m=j.origin_xyz_m,
        origin_rpy_rad=j.origin_rpy_rad,
        axis=axis,
        lower=lower,
        upper=upper,
    )


def chain_from_urdf(
    model: UrdfModel, base_link: str | None = None, tip_link: str | None = None
) -> SerialChain:
    """The serial chain of joints from ``base_link`` down to ``tip_link``.

    Args:
        model: A parsed URDF.
        base_link: First link (default: the URDF's root link).
        tip_link: Last link (default: the only leaf link; required when the tree branches).

    Returns:
        The chain, with ``continuous`` joints as unlimited ``revolute`` ones.

    Raises:
        JointMismatchError: A link is unknown, the tip is not below the base, the tree has several leaves and no
            tip was given, or a joint on the way is floating, planar, mimic or has a zero axis.
    """
    by_child = {j.child: j for j in model.joints}
    links = {j.parent for j in model.joints} | set(by_child)
    base = base_link or root_link(model)
    if tip_link is None:
        leaves = tip_links(model)
        if len(leaves) != 1:
            raise JointMismatchError(
                f"URDF {model.source}: the tree has several tip links ({', '.join(leaves)}); choose one with "
                "--tip-link"
            )
        tip_link = leaves[0]
    for what, link in (("base link", base), ("tip link", tip_link)):
        if link not in links:
            raise JointMismatchError(
                f"URDF {model.source}: no {what} {link!r}; links: {', '.join(sorted(links))}"
            )
    path: list[ChainJoint] = []
    link = tip_link
    while link != base:
        if link not in by_child:
            raise JointMismatchError(f"URDF {model.source}: link {tip_link!r} is not below {base!r}")
        path.append(by_child[link])
        link = by_child[link].parent
    path.reverse()
    chain = SerialChain(tuple(_chain_joint(j, model.source) for j in path), base, tip_link)
    if chain.n_q == 0:
        raise JointMismatchError(f"URDF {model.source}: no movable joint between {base!r} and {tip_link!r}")
    return chain


def corrected_urdf_bytes(
    doc: UrdfDocument, chain: SerialChain, only: Mapping[str, bool] | None = None
) -> bytes:
    """The document with each movable chain joint's ``<origin>`` set from ``chain``.

    Args:
        doc: The original URDF document (not modified by an error; it is modified in place on success).
        chain: A corrected chain whose joints exist in ``doc``.
        only: Optional ``{joint: bool}``; joints mapped to False keep their origin.

    Returns:
        The new file's bytes.
    """
    model = doc.model()
    names = set(model.joint_names)
    missing = [j.name for j in chain.movable if j.name not in names]
    if missing:
        raise UsageError(f"URDF {doc.source}: chain joints {', '.join(missing)} are not in the file")
    for j in chain.movable:
        if only is not None and not only.get(j.name, True):
            continue
        doc.set_origin(j.name, j.origin_xyz_m, j.origin_rpy_rad)
    return doc.to_bytes()
