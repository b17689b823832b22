"""The pieces of the viewer page below the app: page values, the robot drawn in the scene, lights, port check.

See :mod:`robocal.viewer` for the public API and the page state a browser test can read.
"""

from __future__ import annotations

import contextlib
import errno
import html
import io
import math
import socket
import threading
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any, TypeVar

import numpy as np
import numpy.typing as npt

from ..core.arrays import FloatArray
from ..core.se3 import quaternion_from_matrix
from ..errors import BackendNotAvailableError, UsageError
from .access import (
    LOGGER,
    PageAccess,
    exposure_warning,
    guarded_server,
    outward_address,
    parse_allowed_origins,
)
from .latest import Frame
from .model import RobotModel

__all__ = [
    "GHOST_OPACITY",
    "GHOST_RGB",
    "OUTSIDE_RGB",
    "TABLE_HZ",
    "JointReadout",
    "PageUpdate",
    "ReplayControl",
    "ServedPage",
    "check_port_free",
    "joint_table_html",
    "open_server",
    "page_url",
    "plain_lights",
    "polyline_segments",
    "stop_server",
    "stop_thread",
    "wxyz_from_matrix",
]

OUTSIDE_RGB = (0.86, 0.08, 0.08)
"""Colour of a link whose joint is outside its URDF limits (model and panel)."""
GHOST_RGB = (0.25, 0.55, 1.0)
"""Colour of the ``--compare`` ghost."""
GHOST_OPACITY = 0.35


@dataclass(frozen=True)
class JointReadout:
    """One joint at one page update.

    Attributes:
        name: Joint name.
        raw: Raw value from the source (its unit: rad of the motor, ticks, …); NaN when not read.
        q: Calibrated position, rad (m for prismatic).
        q_compare: Position through the ``--compare`` calibration, or NaN without one.
        lower: URDF lower limit (``-inf`` when none).
        upper: URDF upper limit (``+inf`` when none).
        outside: True when ``q`` is outside ``[lower, upper]``.
    """

    name: str
    raw: float
    q: float
    q_compare: float
    lower: float
    upper: float
    outside: bool


@dataclass(frozen=True)
class PageUpdate:
    """What one page update showed; handed to every hook added with :meth:`ViewerApp.add_hook`.

    Attributes:
        frame: The source frame shown.
        q: Calibrated joint positions, shape ``(N,)`` in :attr:`RobotModel.actuated` order.
        q_compare: Ghost joint positions, shape ``(N,)``, or None without a ghost.
        outside: Shape ``(N,)``, joints outside their limits.
        poses: Link → 4×4 world pose of the robot.
        ghost_poses: Link → 4×4 world pose of the ghost, or None.
        joints: Per-joint readouts.
        local: Link → 4×4 pose relative to its parent link (what is sent to the page).
        ghost_local: The same for the ghost, or None.
    """

    frame: Frame
    q: FloatArray
    q_compare: FloatArray | None
    outside: npt.NDArray[np.bool_]
    poses: dict[str, FloatArray]
    ghost_poses: dict[str, FloatArray] | None
    joints: tuple[JointReadout, ...]
    local: dict[str, FloatArray]
    ghost_local: dict[str, FloatArray] | None


class ReplayControl:
    """What the page's replay controls drive (implemented by :class:`robocal.viewer.feeds.ReplayFeed`)."""

    t_start_s: float
    t_end_s: float

    @property
    def playing(self) -> bool:
        """True while playing."""
        raise NotImplementedError

    @property
    def position_s(self) -> float:
        """Current recording time, s."""
        raise NotImplementedError

    def play(self) -> None:
        """Start or resume playing."""
        raise NotImplementedError

    def pause(self) -> None:
        """Pause."""
        raise NotImplementedError

    def seek(self, t_s: float) -> None:
        """Jump to recording time ``t_s`` (clamped to the recording) and show that frame."""
        raise NotImplementedError


def check_port_free(host: str, port: int) -> None:
    """Refuse a port another program listens on (viser would silently move to the next one).

    Raises:
        UsageError: The port is in use or the host cannot be bound.
    """
    if not (0 <= port <= 65535):
        raise UsageError(f"--port {port}: expected 0..65535")
    if port == 0:
        return
    try:
        infos = socket.getaddrinfo(host, port, type=socket.SOCK_STREAM)
    except socket.gaierror as exc:
        raise UsageError(f"--host {host!r}: cannot resolve it ({exc.strerror})") from None
    family, _, _, _, addr = infos[0]
    with socket.socket(family, socket.SOCK_STREAM) as s:
        s.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        try:
            s.bind(addr)
        except OSError as exc:
            if exc.errno == errno.EADDRINUSE:
                raise UsageError(
                    f"port {port} on {host} is in use by another program; pass --port with a free one "
                    "(or --port 0 for any)"
                ) from None
            raise UsageError(f"cannot serve on {host}:{port}: {exc.strerror or exc}") from None


def _fmt(x: float, digits: int = 3) -> str:
    if math.isnan(x):
        return "—"
    if math.isinf(x):
        return "∞" if x > 0 else "−∞"
    return f"{x:+.{digits}f}"


def _lim(x: float) -> str:
    if math.isinf(x):
        return "∞" if x > 0 else "−∞"
    return f"{x:.2f}"


def polyline_segments(points: FloatArray) -> npt.NDArray[np.float32]:
    """``(N, 3)`` points of a polyline → its ``(N − 1, 2, 3)`` segments, float32 (viser's line segments)."""
    return np.stack([points[:-1], points[1:]], axis=1).astype(np.float32)


def wxyz_from_matrix(R: FloatArray) -> tuple[float, float, float, float]:
    """Rotation matrix → unit quaternion (w, x, y, z), renormalised for the page."""
    w, x, y, z = quaternion_from_matrix(R)
    n = math.sqrt(w * w + x * x + y * y + z * z)
    return (w / n, x / n, y / n, z / n)


def _viser(command: str = "robocal view") -> Any:
    try:
        import viser
    except ImportError:
        raise BackendNotAvailableError(f"{command} needs viser: pip install 'robocal[view]'") from None
    return viser


def open_server(viser: Any, host: str, port: int, allowed_origins: Sequence[str] = ()) -> Any:
    """A ``viser.ViserServer`` on ``host:port`` (0: any free port), without viser's own console output.

    The server answers only requests whose Host and Origin are this machine's page's or in ``allowed_origins``
    (:mod:`.access`); a page served beyond the loopback interface is logged as a warning naming its address.

    Raises:
        UsageError: Another program took ``port`` after the port check (viser would have moved to the next),
            or an ``allowed_origins`` value is not an origin.
    """
    access = PageAccess(host, parse_allowed_origins(allowed_origins))
    with contextlib.redirect_stdout(io.StringIO()), guarded_server(access):  # the CLI prints our URL, not viser's
        server = viser.ViserServer(host=host, port=port, label="robocal", verbose=False)
    if port and server.get_port() != port:  # lost a race for the port
        server.stop()
        raise UsageError(f"port {port} on {host} is in use by another program")
    warning = exposure_warning(host, page_url(host, server.get_port()))
    if warning is not None:
        LOGGER.warning(warning)
    return server


def stop_server(server: Any) -> None:
    """Stop a server made by :func:`open_server` (without its "(viser) Server stopped" line)."""
    with contextlib.redirect_stdout(io.StringIO()):
        server.stop()


_Page = TypeVar("_Page", bound="ServedPage")


class ServedPage:
    """A page a viser server serves (``robocal view``, ``robocal ur view``): its port and address.

    Attributes:
        host: Interface served on.
        requested_port: The port asked for (0: any free one).
        server: The ``viser.ViserServer`` while started, else None.
    """

    host: str
    requested_port: int
    server: Any

    @property
    def port(self) -> int:
        """The port served on (the requested one before :meth:`start`)."""
        return int(self.server.get_port()) if self.server is not None else self.requested_port

    @property
    def url(self) -> str:
        """The page's address."""
        return page_url(self.host, self.port)

    def stop(self) -> None:
        """Stop the server (idempotent)."""
        if self.server is not None:
            server, self.server = self.server, None
            stop_server(server)

    def __enter__(self: _Page) -> _Page:
        return self

    def __exit__(self, *exc: object) -> None:
        self.stop()


def stop_thread(stop: threading.Event, thread: threading.Thread | None, timeout_s: float = 5.0) -> None:
    """Ask a loop thread to end (set ``stop``) and wait for it, at most ``timeout_s``.

    The calling thread is never joined (a loop may stop its own page or feed).
    """
    stop.set()
    if thread is not None and thread is not threading.current_thread():
        thread.join(timeout=timeout_s)


def page_url(host: str, port: int) -> str:
    """The address of a page served on ``host:port`` (wildcard: this machine's outward address; IPv6 bracketed)."""
    if host in ("0.0.0.0", "::", ""):
        host = outward_address()
    if ":" in host:
        host = f"[{host}]"
    return f"http://{host}:{port}/"


class _Robot:
    """One drawn copy of the model (the robot or its ghost): a frame per link, meshes under it."""

    def __init__(
        self,
        server: Any,
        model: RobotModel,
        root: str,
        *,
        rgb: tuple[float, float, float] | None,
        opacity: float | None,
    ) -> None:
        self.root = root
        self.frames: dict[str, Any] = {}
        self.meshes: dict[str, list[tuple[Any, tuple[float, float, float]]]] = {}
        self.last: dict[str, FloatArray] = {}
        self.rgb_now: dict[str, tuple[float, float, float]] = {}
        server.scene.add_frame(root, show_axes=False)
        parent_of = {j.child: j.parent for j in model.joints}
        index = {link: k for k, link in enumerate(model.links)}
        self.paths: dict[str, str] = {}
        for link in model.links:  # parents first: nested frames, so a joint move is one rotation message
            parent = parent_of.get(link)
            base = root if parent is None else self.paths[parent]
            self.paths[link] = f"{base}/L{index[link]}"
            self.frames[link] = server.scene.add_frame(self.paths[link], show_axes=False)
        count: dict[str, int] = {}
        for shape in model.shapes:
            i = count.get(shape.link, 0)
            count[shape.link] = i + 1
            color = rgb if rgb is not None else shape.rgba[:3]
            alpha = opacity if opacity is not None else (shape.rgba[3] if shape.rgba[3] < 1.0 else None)
            handle = server.scene.add_mesh_simple(
                f"{self.paths[shape.link]}/s{i}", shape.vertices, shape.faces, color=color, opacity=alpha
            )
            self.meshes.setdefault(shape.link, []).append((handle, color))
            self.rgb_now[shape.link] = color

    def pose(self, local: dict[str, FloatArray]) -> None:
        """Set every link's pose relative to its parent link (only what changed is sent)."""
        for link, T in local.items():
            last = self.last.get(link)
            h = self.frames[link]
            if last is None or not np.array_equal(last[:3, :3], T[:3, :3]):
                h.wxyz = wxyz_from_matrix(T[:3, :3])
            if last is None or not np.array_equal(last[:3, 3], T[:3, 3]):
                h.position = (float(T[0, 3]), float(T[1, 3]), float(T[2, 3]))
            self.last[link] = T

    def tint(self, link: str, rgb: tuple[float, float, float] | None) -> None:
        """Colour a link's meshes ``rgb`` (None: back to their own colour)."""
        for handle, own in self.meshes.get(link, []):
            want = own if rgb is None else rgb
            if self.rgb_now.get(link) != want:
                # viser's mesh colour property is 0..255 integers: 0..1 floats would be truncated to black
                handle.color = tuple(round(255.0 * min(1.0, max(0.0, c))) for c in want)
        if link in self.meshes:
            self.rgb_now[link] = rgb if rgb is not None else self.meshes[link][0][1]

    def set_visible(self, visible: bool) -> None:
        for h in self.frames.values():
            h.visible = visible


TABLE_HZ = 10.0
"""Most redraws of the joint table per second (the pose and the page state follow every update)."""


def plain_lights(server: Any) -> None:
    """Plain ambient + directional lights instead of viser's image-based lighting.

    The default environment map costs about 20 s per page load on a software renderer (no GPU) and slows every
    frame there; simple-shape robots gain nothing from it.
    """
    server.scene.configure_environment_map(hdri=None)
    server.scene.add_light_ambient("/light/ambient", intensity=1.2)
    server.scene.add_light_directional("/light/sun", intensity=1.8, position=(2.0, -2.0, 3.0))


def joint_table_html(model: RobotModel, update: PageUpdate | None, *, ghost: bool, raw_unit: str) -> str:
    """The joint panel's table (``#robocal-joints``): raw, calibrated and ghost value, limits and a bar per joint."""
    unit = html.escape(raw_unit)
    head = (
        '<table id="robocal-joints" style="width:100%;font-size:0.8em;border-collapse:collapse">'
        f"<tr><th align=left>joint</th><th align=right>raw ({unit})</th><th align=right>q (rad)</th>"
        + ("<th align=right>ghost</th>" if ghost else "")
        + "<th align=right>limits</th><th>range</th></tr>"
    )
    rows = []
    for i, name in enumerate(model.actuated):
        j = update.joints[i] if update is not None else None
        raw = j.raw if j else math.nan
        q = j.q if j else math.nan
        qc = j.q_compare if j else math.nan
        lo, hi = float(model.lower[i]), float(model.upper[i])
        outside = bool(j.outside) if j else False
        colour = "#c00" if outside else "#222"
        if math.isfinite(lo) and math.isfinite(hi) and hi > lo and not math.isnan(q):
            frac = min(1.0, max(0.0, (q - lo) / (hi - lo)))
        else:
            frac = 0.5 if not math.isnan(q) else math.nan
        bar = ""
        if not math.isnan(frac):
            bar = (
                f'<div style="position:absolute;left:calc({100 * frac:.1f}% - 2px);top:0;width:4px;'
                f'height:100%;background:{"#d00" if outside else "#36c"}"></div>'
            )
        rows.append(
            f'<tr class="robocal-joint" data-joint="{html.escape(name)}" data-outside="{int(outside)}" '
            f'data-q="{"" if math.isnan(q) else repr(q)}" style="color:{colour}">'
            f"<td>{html.escape(name)}</td><td align=right>{_fmt(raw)}</td><td align=right>{_fmt(q)}</td>"
            + (f"<td align=right>{_fmt(qc)}</td>" if ghost else "")
            + f'<td align=right style="white-space:nowrap">{_lim(lo)}…{_lim(hi)}</td>'
            '<td style="width:25%"><div style="position:relative;height:8px;background:#ddd;'
            f'border:1px solid {"#d00" if outside else "#bbb"}">{bar}</div></td></tr>'
        )
    return head + "".join(rows) + "</table>"
