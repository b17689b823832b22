"""The robot the viewer draws: joints, forward kinematics and link shapes from a URDF (no viser here).

The URDF is read twice: first by robocal's hardened lxml reader (:func:`robocal.formats.urdf.parse_urdf`: no
entities, no network, a clear :class:`~robocal.errors.FileFormatError` for a malformed file), then the same
bytes by yourdfpy for links, visuals, materials and mimic joints. Forward kinematics is a few numpy products
per joint (:meth:`RobotModel.link_poses`), fast enough for two robots at the page rate.

Meshes (``<mesh filename=…>``) resolve, in order, against:

1. ``package://NAME/rest`` → ``DIR/rest`` for each ``--package-path NAME=DIR``;
2. the URDF's folder: ``rest`` (and for ``package://NAME/rest`` also ``NAME/rest``) under the URDF's folder
   and under its parent and grandparent (the usual ``<pkg>/urdf/robot.urdf`` + ``<pkg>/meshes/…`` layout);
3. ``file://`` URLs and absolute paths as given.

A mesh that is not found or does not load is replaced by simple shapes (a rod to each child joint and a ball at
the joint) and listed in :attr:`RobotModel.warnings` — one warning for all of them. A link without any
``<visual>`` gets the same simple shapes without a warning (the Lite example has none).
"""

from __future__ import annotations

import io
import math
import os
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt

from ..core.arrays import FloatArray
from ..errors import BackendNotAvailableError, FileFormatError, UsageError
from ..fileio import MAX_URDF_BYTES, read_bytes
from ..formats.urdf import parse_urdf

__all__ = [
    "DEFAULT_RGBA",
    "JointInfo",
    "LinkShape",
    "RobotModel",
    "load_robot_model",
    "parse_package_paths",
    "resolve_mesh",
]

RGBA = tuple[float, float, float, float]
DEFAULT_RGBA: RGBA = (0.42, 0.48, 0.58, 1.0)
"""Colour of a link without a URDF material."""
STICK_ROD_RADIUS_M = 0.012
STICK_BALL_RADIUS_M = 0.022
"""The stick figure drawn for a URDF without visuals: rods along the joints, a ball at each link origin."""
MOVABLE = ("revolute", "continuous", "prismatic")


@dataclass(frozen=True)
class JointInfo:
    """One URDF joint as the viewer needs it.

    Attributes:
        name: Joint name.
        type: URDF type (``revolute``, ``continuous``, ``prismatic``, ``fixed``, …).
        parent: Parent link.
        child: Child link.
        T_parent_joint: ``<origin>`` as a 4×4 homogeneous transform, parent link frame.
        axis: Unit axis, shape ``(3,)``, joint frame.
        lower: Lower limit, rad (m for prismatic); ``-inf`` when the URDF gives none (continuous).
        upper: Upper limit; ``+inf`` when none.
        mimic: ``(joint, multiplier, offset)`` when the joint mimics another, else None.
    """

    name: str
    type: str
    parent: str
    child: str
    T_parent_joint: FloatArray
    axis: FloatArray
    lower: float = -math.inf
    upper: float = math.inf
    mimic: tuple[str, float, float] | None = None

    @property
    def is_actuated(self) -> bool:
        """True for a movable joint that does not mimic another (the joints a source reports)."""
        return self.type in MOVABLE and self.mimic is None


@dataclass(frozen=True)
class LinkShape:
    """One triangle mesh drawn rigidly with a link.

    Attributes:
        link: The link it moves with.
        vertices: Shape ``(V, 3)``, m, link frame (the visual's origin and scale applied).
        faces: Shape ``(F, 3)`` vertex indices.
        rgba: Colour, 0..1.
        kind: ``box``, ``cylinder``, ``sphere``, ``mesh`` or ``fallback`` (simple shapes drawn instead).
    """

    link: str
    vertices: FloatArray
    faces: npt.NDArray[np.int32]
    rgba: RGBA
    kind: str


@dataclass
class RobotModel:
    """Joints, links and shapes of one URDF.

    Attributes:
        name: ``<robot name>``.
        source: The URDF path.
        root_link: The link with no parent.
        joints: Every joint, parents before children.
        actuated: Names of the actuated joints (movable, not mimic) in tree order (depth first from the root,
            siblings in document order): the joint axis of every array.
        links: Link names, parents before children (root first).
        shapes: Shapes to draw, per link.
        warnings: Problems found while loading (missing meshes), for the CLI and the page.
    """

    name: str
    source: str
    root_link: str
    joints: tuple[JointInfo, ...]
    actuated: tuple[str, ...]
    links: tuple[str, ...]
    shapes: tuple[LinkShape, ...]
    warnings: list[str] = field(default_factory=list)

    def __post_init__(self) -> None:
        self._index = {n: i for i, n in enumerate(self.actuated)}
        self._by_name = {j.name: j for j in self.joints}
        self.lower: FloatArray = np.array([self._by_name[n].lower for n in self.actuated], dtype=np.float64)
        self.upper: FloatArray = np.array([self._by_name[n].upper for n in self.actuated], dtype=np.float64)

    def joint(self, name: str) -> JointInfo:
        """The joint called ``name``."""
        return self._by_name[name]

    def child_link(self, joint: str) -> str:
        """The link a joint moves."""
        return self._by_name[joint].child

    def outside_limits(self, q: npt.ArrayLike) -> npt.NDArray[np.bool_]:
        """Which actuated joints lie outside their URDF limits, shape ``(N,)`` (NaN is not outside)."""
        qa = np.asarray(q, dtype=np.float64)
        with np.errstate(invalid="ignore"):
            out: npt.NDArray[np.bool_] = (qa < self.lower) | (qa > self.upper)
        return out

    def link_poses(self, q: npt.ArrayLike) -> dict[str, FloatArray]:
        """Forward kinematics: the world pose of every link.

        Args:
            q: Actuated joint positions, shape ``(N,)`` in :attr:`actuated` order, rad (m for prismatic);
                NaN is drawn as 0.

        Returns:
            Link name → 4×4 ``T_world_link``.
        """
        return self.poses(q)[0]

    def poses(self, q: npt.ArrayLike) -> tuple[dict[str, FloatArray], dict[str, FloatArray]]:
        """World poses and parent-relative poses of every link in one pass.

        Returns:
            ``(T_world_link, T_parent_link)``, each link name → 4×4 (the root's parent pose is the identity).
        """
        qa = np.nan_to_num(np.asarray(q, dtype=np.float64), nan=0.0)
        if qa.shape != (len(self.actuated),):
            raise UsageError(f"expected {len(self.actuated)} joint positions, got shape {qa.shape}")
        values = {n: float(qa[i]) for i, n in enumerate(self.actuated)}
        world = {self.root_link: np.eye(4)}
        local = {self.root_link: np.eye(4)}
        for j in self.joints:
            T = j.T_parent_joint
            if j.type in MOVABLE:
                if j.mimic is not None:
                    src, mult, off = j.mimic
                    v = values.get(src, 0.0) * mult + off
                else:
                    v = values[j.name]
                T = T @ _motion(j.type, j.axis, v)
            local[j.child] = T
            world[j.child] = world[j.parent] @ T
        return world, local


def _motion(kind: str, axis: FloatArray, value: float) -> FloatArray:
    """The joint's motion by ``value`` about/along ``axis`` as a 4×4 transform."""
    M = np.eye(4)
    if kind == "prismatic":
        M[:3, 3] = axis * value
        return M
    x, y, z = axis
    c, s = math.cos(value), math.sin(value)
    C = 1.0 - c
    M[:3, :3] = (
        (c + x * x * C, x * y * C - z * s, x * z * C + y * s),
        (y * x * C + z * s, c + y * y * C, y * z * C - x * s),
        (z * x * C - y * s, z * y * C + x * s, c + z * z * C),
    )
    return M


def parse_package_paths(items: Sequence[str]) -> dict[str, Path]:
    """``NAME=DIR`` items (``--package-path``, repeatable) → ``{NAME: DIR}``.

    Raises:
        UsageError: An item without ``=``, an empty name, or a folder that does not exist.
    """
    out: dict[str, Path] = {}
    for item in items:
        name, sep, folder = item.partition("=")
        name = name.strip()
        if not sep or not name or not folder:
            raise UsageError(f"--package-path {item!r}: expected NAME=DIR, e.g. so101_description=./so101")
        path = Path(folder).expanduser()
        if not path.is_dir():
            raise UsageError(f"--package-path {item!r}: {path} is not a folder")
        out[name] = path
    return out


def resolve_mesh(filename: str, urdf_dir: Path, package_paths: Mapping[str, Path]) -> Path | None:
    """The file a URDF ``<mesh filename>`` names, or None when it is not found (see the module docstring)."""
    candidates: list[Path] = []
    if filename.startswith("package://"):
        rest = filename[len("package://") :]
        pkg, _, sub = rest.partition("/")
        if pkg in package_paths:
            candidates.append(package_paths[pkg] / sub)
        for base in (urdf_dir, urdf_dir.parent, urdf_dir.parent.parent):
            candidates += [base / sub, base / pkg / sub]
    elif filename.startswith("file://"):
        candidates.append(Path(filename[len("file://") :]))
    else:
        p = Path(filename)
        candidates.append(p if p.is_absolute() else urdf_dir / p)
    for c in candidates:
        if c.is_file():
            return c
    return None


def _require_yourdfpy() -> Any:
    try:
        import trimesh  # noqa: F401
        import yourdfpy
    except ImportError as exc:
        raise BackendNotAvailableError(
            f"robocal view needs yourdfpy and trimesh ({exc.name} is missing): pip install 'robocal[view]'"
        ) from None
    return yourdfpy


def _rgba4(values: Any) -> RGBA | None:
    v = [float(x) for x in np.asarray(values, dtype=np.float64).reshape(-1)[:4]]
    if len(v) != 4 or not all(math.isfinite(x) for x in v):
        return None
    c = [min(1.0, max(0.0, x)) for x in v]
    return (c[0], c[1], c[2], c[3])


def _rgba(material: Any, named: Mapping[str, RGBA]) -> RGBA:
    if material is None:
        return DEFAULT_RGBA
    color = getattr(material, "color", None)
    if color is not None and getattr(color, "rgba", None) is not None:
        found = _rgba4(color.rgba)
        if found is not None:
            return found
    name = getattr(material, "name", None)
    if isinstance(name, str) and name in named:
        return named[name]
    return DEFAULT_RGBA


def _mesh_arrays(mesh: Any) -> tuple[FloatArray, npt.NDArray[np.int32]]:
    return np.asarray(mesh.vertices, dtype=np.float64), np.asarray(mesh.faces, dtype=np.int32)


def _load_mesh(path: Path, scale: Any) -> Any:
    """A trimesh of the file (scenes concatenated), scaled; raises on anything unreadable."""
    import trimesh

    loaded = trimesh.load(str(path), force="mesh")
    if not isinstance(loaded, trimesh.Trimesh) or len(loaded.faces) == 0:
        raise ValueError("no triangles")
    if scale is not None:
        s = np.asarray(scale, dtype=np.float64).reshape(-1)
        loaded.apply_scale(s if s.size == 3 else float(s[0]))  # type: ignore[no-untyped-call]
    return loaded


def _fallback_shapes(link: str, children: Sequence[JointInfo], rgba: RGBA, root: bool) -> list[LinkShape]:
    """A ball at the link origin and a rod to each child joint (link frame)."""
    import trimesh

    out = []
    ball = trimesh.creation.icosphere(subdivisions=2, radius=STICK_BALL_RADIUS_M * (1.4 if root else 1.0))
    v, f = _mesh_arrays(ball)
    out.append(LinkShape(link, v, f, rgba, "fallback"))
    for j in children:
        d = j.T_parent_joint[:3, 3]
        length = float(np.linalg.norm(d))
        if length < 1e-4:
            continue
        rod = trimesh.creation.cylinder(radius=STICK_ROD_RADIUS_M, segment=np.array([np.zeros(3), d]), sections=12)
        v, f = _mesh_arrays(rod)
        out.append(LinkShape(link, v, f, rgba, "fallback"))
    return out


def load_robot_model(
    urdf_path: str | os.PathLike[str], package_paths: Mapping[str, Path] | None = None
) -> RobotModel:
    """Read a URDF into a :class:`RobotModel` (meshes loaded, missing ones replaced by simple shapes).

    Args:
        urdf_path: The URDF file.
        package_paths: ``package://NAME`` → folder.

    Raises:
        FileFormatError: The URDF does not parse, or its links do not form one tree.
        BackendNotAvailableError: yourdfpy/trimesh are not installed.
    """
    yourdfpy = _require_yourdfpy()
    import trimesh

    path = Path(urdf_path)
    data = read_bytes(path, "URDF", limit=MAX_URDF_BYTES)
    parse_urdf(data, str(path))  # robocal's hardened reader: a clear error for a malformed file
    try:
        urdf = yourdfpy.URDF.load(
            io.BytesIO(data),
            build_scene_graph=False,
            load_meshes=False,
            build_collision_scene_graph=False,
            load_collision_meshes=False,
        )
    except Exception as exc:  # yourdfpy raises plain exceptions of many kinds
        raise FileFormatError(f"URDF {path}: yourdfpy cannot read it: {exc}") from None
    robot = urdf.robot
    link_names = [lk.name for lk in robot.links]
    children_of: dict[str, list[Any]] = {}
    has_parent = set()
    for j in robot.joints:
        children_of.setdefault(j.parent, []).append(j)
        has_parent.add(j.child)
    roots = [n for n in link_names if n not in has_parent]
    if len(roots) != 1:
        raise FileFormatError(
            f"URDF {path}: expected one root link, found {len(roots)} ({', '.join(roots[:5]) or 'none'})"
        )
    root = roots[0]
    ordered: list[JointInfo] = []
    links = [root]
    stack: list[Any] = list(reversed(children_of.get(root, [])))
    while stack:  # depth first from the root, siblings in document order
        j = stack.pop()
        if j.child in links:
            raise FileFormatError(f"URDF {path}: link {j.child!r} has more than one parent joint (or a loop)")
        axis = np.asarray(j.axis if j.axis is not None else (1.0, 0.0, 0.0), dtype=np.float64)
        norm = float(np.linalg.norm(axis))
        if j.type in MOVABLE and not (math.isfinite(norm) and norm > 0):
            raise FileFormatError(f"URDF {path}: joint {j.name!r} has a zero axis")
        axis = axis / norm if norm > 0 else axis
        lo, up = -math.inf, math.inf
        if j.type in ("revolute", "prismatic") and j.limit is not None:
            lo = float(j.limit.lower) if j.limit.lower is not None else -math.inf
            up = float(j.limit.upper) if j.limit.upper is not None else math.inf
        mimic = None
        if j.mimic is not None:
            mimic = (
                str(j.mimic.joint),
                float(1.0 if j.mimic.multiplier is None else j.mimic.multiplier),
                float(0.0 if j.mimic.offset is None else j.mimic.offset),
            )
        origin = np.asarray(j.origin if j.origin is not None else np.eye(4), dtype=np.float64)
        ordered.append(JointInfo(j.name, j.type, j.parent, j.child, origin, axis, lo, up, mimic))
        links.append(j.child)
        stack.extend(reversed(children_of.get(j.child, [])))
    if len(links) != len(link_names):
        lost = sorted(set(link_names) - set(links))
        raise FileFormatError(f"URDF {path}: links not connected to {root!r}: {', '.join(lost[:5])}")
    named: dict[str, RGBA] = {}
    for m in robot.materials:
        colour = _rgba4(m.color.rgba) if m.name and m.color is not None else None
        if colour is not None:
            named[str(m.name)] = colour
    joint_children: dict[str, list[JointInfo]] = {}
    for ji in ordered:
        joint_children.setdefault(ji.parent, []).append(ji)
    urdf_dir = path.resolve().parent
    packages = dict(package_paths or {})
    shapes: list[LinkShape] = []
    missing: list[str] = []
    for lk in robot.links:
        drawn = False
        fell_back = False
        rgba = DEFAULT_RGBA
        for vis in lk.visuals:
            geom = vis.geometry
            T = np.asarray(vis.origin if vis.origin is not None else np.eye(4), dtype=np.float64)
            rgba = _rgba(vis.material, named)
            mesh: Any = None
            kind = ""
            if geom is None:
                continue
            if geom.box is not None:
                mesh, kind = trimesh.creation.box(extents=np.asarray(geom.box.size, dtype=np.float64)), "box"
            elif geom.cylinder is not None:
                mesh = trimesh.creation.cylinder(
                    radius=float(geom.cylinder.radius), height=float(geom.cylinder.length), sections=24
                )
                kind = "cylinder"
            elif geom.sphere is not None:
                mesh, kind = (
                    trimesh.creation.icosphere(subdivisions=2, radius=float(geom.sphere.radius)),
                    "sphere",
                )
            elif geom.mesh is not None:
                found = resolve_mesh(str(geom.mesh.filename), urdf_dir, packages)
                if found is None:
                    missing.append(f"{geom.mesh.filename} (link {lk.name}: not found)")
                    fell_back = True
                    continue
                try:
                    mesh, kind = _load_mesh(found, geom.mesh.scale), "mesh"
                except Exception as exc:  # trimesh raises many kinds on a damaged file
                    missing.append(f"{found} (link {lk.name}: {exc or type(exc).__name__})")
                    fell_back = True
                    continue
            if mesh is None:
                continue
            mesh.apply_transform(T)
            v, f = _mesh_arrays(mesh)
            shapes.append(LinkShape(lk.name, v, f, rgba, kind))
            drawn = True
        if not drawn or fell_back:
            shapes += _fallback_shapes(lk.name, joint_children.get(lk.name, []), rgba, lk.name == root)
    warnings = []
    if missing:
        more = f" and {len(missing) - 1} more" if len(missing) > 1 else ""
        warnings.append(
            f"{len(missing)} mesh(es) of {path.name} could not be loaded and are drawn as simple shapes "
            f"(first: {missing[0]}{more}); pass --package-path NAME=DIR to find package:// meshes"
        )
    actuated = tuple(j.name for j in ordered if j.is_actuated)
    if not actuated:
        raise FileFormatError(f"URDF {path}: no movable joints to show")
    by_name = {j.name for j in ordered}
    for ji in ordered:
        if ji.mimic is not None and ji.mimic[0] not in by_name:
            raise FileFormatError(f"URDF {path}: joint {ji.name!r} mimics unknown joint {ji.mimic[0]!r}")
    return RobotModel(
        str(robot.name), str(path), root, tuple(ordered), actuated, tuple(links), tuple(shapes), warnings
    )
