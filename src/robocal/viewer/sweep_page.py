"""The sweep on the model: each joint's swept arc drawn against its URDF limits, coloured by status code.

``robocal sweep … --view`` (and ``robocal lerobot calibrate … --view``) open a :class:`~robocal.viewer.app.ViewerApp`
on the robot's URDF and add a :class:`SweepOverlay` to it. Per joint, in the joint's own frame (so the arcs move
with the parent link):

* a thin dark arc over the URDF range ``[lower, upper]``;
* a thick arc over the swept range ``[sampled_min, sampled_max]`` (identity frame ``direction·raw``: the
  values the report's codes are computed from), coloured by the joint's status code, the same code the sweep
  report gives (:attr:`robocal.core.sweep.JointSweep.status`): ``ok`` green, ``not_swept`` grey,
  ``span_mismatch`` orange, ``no_overlap`` red, ``wrap_in_travel`` purple, any other warning yellow;
* the robot itself posed at the newest reading (identity frame), so a joint beyond its limits turns red.

A flipped direction shows as a swept arc on the wrong side of the limits (``no_overlap``), a stop that is not
where the URDF says as an arc longer or shorter than the limit arc (``span_mismatch``).

The overlay's state is published in the page as JSON (``#robocal-sweep[data-sweep]``): per joint the status,
colour, both ranges and the current reading.
"""

from __future__ import annotations

import html
import json
import math
import threading
import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
import numpy.typing as npt

from ..core.arrays import FloatArray
from ..core.profile_auto import NOT_SEARCHED
from ..core.stop_types import FAIL_CODES
from ..core.sweep_result import SweepResult
from .app import PageUpdate, ViewerApp
from .model import RobotModel
from .scene import polyline_segments, wxyz_from_matrix

__all__ = [
    "FAIL_RGB",
    "LIMIT_RGB",
    "LIVE_RGB",
    "OTHER_RGB",
    "STATUS_RGB",
    "JointArc",
    "SweepOverlay",
    "SweepWebView",
    "arc_points",
    "json_num",
    "open_sweep_page",
    "status_json",
    "status_rgb",
]

STATUS_RGB: dict[str, tuple[int, int, int]] = {
    "ok": (30, 170, 60),
    "not_swept": (150, 150, 150),
    "span_mismatch": (245, 150, 0),
    "no_overlap": (225, 20, 20),
    "wrap_in_travel": (150, 50, 210),
}
"""Colour of a swept arc per status code (the codes of the sweep report)."""
OTHER_RGB = (225, 200, 0)
"""Colour of a swept arc whose status is another warning (offset_large, direction_flipped, …)."""
LIMIT_RGB = (40, 40, 40)
"""Colour of the URDF limit arcs."""
LIVE_RGB: dict[str, tuple[int, int, int]] = {"searching": (20, 110, 240)}
"""Colour of a joint the automatic stop search is moving (its range travelled so far)."""
FAIL_RGB = (200, 0, 110)
"""Colour of a joint whose automatic stop search failed (its auto report code: missing_stop, blocked, …)."""
ARC_SEGMENTS = 48


def status_rgb(status: str) -> tuple[int, int, int]:
    """The colour of a status code (sweep report codes, ``searching``, auto-search failure codes).

    A joint the automatic search left alone because its profile gives it no stop (``not_searched``) is drawn
    like a joint the sweep did not move (``not_swept``, grey): nothing was measured, and nothing failed.
    """
    if status in STATUS_RGB:
        return STATUS_RGB[status]
    if status == NOT_SEARCHED:
        return STATUS_RGB["not_swept"]
    if status in LIVE_RGB:
        return LIVE_RGB[status]
    return FAIL_RGB if status in FAIL_CODES else OTHER_RGB


def status_json(name: str, status: str) -> dict[str, Any]:
    """The first keys of a joint's page state: name, status and its colour (None while ``waiting``)."""
    return {
        "name": name,
        "status": status,
        "color": list(status_rgb(status)) if status != "waiting" else None,
    }


def json_num(x: float) -> float | None:
    """A number for the page state: NaN and inf become None (JSON has neither)."""
    return float(x) if math.isfinite(x) else None


def arc_points(
    axis: npt.ArrayLike, start_rad: float, end_rad: float, radius_m: float, n: int = ARC_SEGMENTS
) -> FloatArray:
    """Points of an arc about ``axis`` (unit, joint frame) from ``start_rad`` to ``end_rad``, shape ``(n+1, 3)``.

    The angle is measured from a fixed direction ``u`` perpendicular to the axis (the joint frame's x axis,
    or y when the axis is x), counter-clockwise about the axis: the joint's rotation by ``θ`` carries ``u``
    to the arc point at ``θ``.
    """
    a = np.asarray(axis, dtype=np.float64)
    a = a / np.linalg.norm(a)
    ref = np.array([1.0, 0.0, 0.0]) if abs(a[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    u = ref - a * float(ref @ a)
    u /= np.linalg.norm(u)
    v = np.cross(a, u)
    th = np.linspace(start_rad, end_rad, n + 1)
    out: FloatArray = radius_m * (np.cos(th)[:, None] * u + np.sin(th)[:, None] * v)
    return out


def line_rgb(rgb: tuple[int, int, int]) -> npt.NDArray[np.uint8]:
    """The colour to give viser's line segments so that ``rgb`` (sRGB) is what reaches the screen.

    viser's line material takes its vertex colours as linear values and encodes them to sRGB again, which
    washes them out (orange turned yellow); decoding them once here cancels that.
    """
    c = np.asarray(rgb, dtype=np.float64) / 255.0
    lin = np.where(c <= 0.04045, c / 12.92, ((c + 0.055) / 1.055) ** 2.4)
    return np.asarray(np.round(lin * 255.0), dtype=np.uint8)


@dataclass(frozen=True)
class JointArc:
    """What the overlay shows for one joint.

    Attributes:
        name: Joint name.
        status: Status code (``ok``, ``not_swept``, …), or ``waiting`` before any reading.
        lower: URDF lower limit, rad.
        upper: URDF upper limit, rad.
        sampled_min: Swept minimum (identity frame), rad; NaN before a reading.
        sampled_max: Swept maximum, rad.
        current: Newest reading, rad.
    """

    name: str
    status: str
    lower: float
    upper: float
    sampled_min: float
    sampled_max: float
    current: float

    def to_json(self) -> dict[str, Any]:
        """Plain data for the page state (NaN becomes None)."""
        return {
            **status_json(self.name, self.status),
            "lower": json_num(self.lower),
            "upper": json_num(self.upper),
            "sampled_min": json_num(self.sampled_min),
            "sampled_max": json_num(self.sampled_max),
            "current": json_num(self.current),
        }


class SweepOverlay:
    """A :meth:`ViewerApp.add_hook` hook drawing the limit and swept arcs of each joint.

    Args:
        app: The started page.
        radius_m: Arc radius; default: a tenth of the robot's size at rest (at least 2 cm).
    """

    def __init__(self, app: ViewerApp, radius_m: float | None = None) -> None:
        self.app = app
        self.model: RobotModel = app.model
        self.names = tuple(self.model.actuated)
        if radius_m is None:
            rest = self.model.link_poses(np.zeros(len(self.names)))
            size = max((float(np.linalg.norm(T[:3, 3])) for T in rest.values()), default=0.2)
            radius_m = max(0.02, 0.1 * size)
        self.radius_m = float(radius_m)
        self._lock = threading.Lock()
        self._draw_lock = threading.Lock()
        self._arcs: dict[str, JointArc] = {
            n: JointArc(
                n,
                "waiting",
                float(self.model.joint(n).lower),
                float(self.model.joint(n).upper),
                math.nan,
                math.nan,
                math.nan,
            )
            for n in self.names
        }
        self._drawn: dict[str, tuple[str, float, float]] = {}
        self._handles: dict[str, Any] = {}
        self._state: Any = None
        self.updates = 0
        self._build()
        app.add_hook(self)

    # --------------------------------------------------------------------------------------- data in
    def set_ranges(
        self,
        sampled_min: Mapping[str, float],
        sampled_max: Mapping[str, float],
        current: Mapping[str, float],
        status: Mapping[str, str],
    ) -> None:
        """Update the joints named in the mappings (thread-safe; drawn at the next page update)."""
        with self._lock:
            for n in self.names:
                if n not in status:
                    continue
                old = self._arcs[n]
                self._arcs[n] = JointArc(
                    n,
                    status[n],
                    old.lower,
                    old.upper,
                    float(sampled_min.get(n, math.nan)),
                    float(sampled_max.get(n, math.nan)),
                    float(current.get(n, math.nan)),
                )

    def set_result(self, result: SweepResult, current: Mapping[str, float] | None = None) -> None:
        """Show a sweep result (live or final): ranges and each joint's status code as the report has it."""
        cur = current or {}
        self.set_ranges(
            {j.name: j.sampled_min for j in result.joints},
            {j.name: j.sampled_max for j in result.joints},
            {j.name: cur.get(j.name, math.nan) for j in result.joints},
            {j.name: j.status for j in result.joints},
        )
        with self._lock:  # the report's limits win (a profile may narrow the URDF's)
            for j in result.joints:
                if j.name in self._arcs:
                    a = self._arcs[j.name]
                    self._arcs[j.name] = JointArc(
                        a.name, a.status, j.lower, j.upper, a.sampled_min, a.sampled_max, a.current
                    )

    def arcs(self) -> tuple[JointArc, ...]:
        """The current per-joint state."""
        with self._lock:
            return tuple(self._arcs[n] for n in self.names)

    def status(self) -> dict[str, Any]:
        """The overlay's page state."""
        return {
            "updates": self.updates,
            "radius_m": self.radius_m,
            "joints": [a.to_json() for a in self.arcs()],
        }

    # --------------------------------------------------------------------------------------- drawing
    def _joint_path(self, name: str) -> str:
        j = self.model.joint(name)
        robot = self.app.robot
        assert robot is not None
        return f"{robot.paths[j.parent]}/sweep_{self.names.index(name)}"

    def _build(self) -> None:
        server = self.app.server
        if server is None:
            return
        for k, n in enumerate(self.names):
            j = self.model.joint(n)
            T = j.T_parent_joint
            frame = server.scene.add_frame(
                self._joint_path(n),
                show_axes=False,
                wxyz=wxyz_from_matrix(T[:3, :3]),
                position=tuple(float(v) for v in T[:3, 3]),
            )
            lo, hi = self._arcs[n].lower, self._arcs[n].upper
            if not (math.isfinite(lo) and math.isfinite(hi)):
                lo, hi = -math.pi, math.pi
            limit = server.scene.add_line_segments(
                f"{self._joint_path(n)}/limits",
                polyline_segments(arc_points(j.axis, lo, hi, self.radius_m)),
                line_rgb(LIMIT_RGB),
                thickness=0.15 * self.radius_m,
            )
            swept = server.scene.add_line_segments(
                f"{self._joint_path(n)}/swept",
                polyline_segments(arc_points(j.axis, 0.0, 0.0, 1.25 * self.radius_m)),
                # one colour per vertex from the start: a line node created with a single colour is drawn
                # white by the page after a per-vertex colour update (until a reload)
                np.tile(line_rgb(STATUS_RGB["not_swept"]), (ARC_SEGMENTS, 2, 1)),
                thickness=0.35 * self.radius_m,
                visible=False,
            )
            self._handles[n] = {"frame": frame, "limit": limit, "swept": swept, "k": k}
        legend = " · ".join(
            f'<span style="color:rgb{c}">■</span> {html.escape(code)}' for code, c in STATUS_RGB.items()
        )
        server.gui.add_html(
            f'<div style="font-size:0.8em">swept arcs: {legend} · <span style="color:rgb{OTHER_RGB}">■</span> '
            "other warning; thin dark arc: URDF limits</div>"
        )
        self._state = server.gui.add_html(self._state_html())

    def _state_html(self) -> str:
        state = html.escape(json.dumps(self.status(), separators=(",", ":")), quote=True)
        return f'<div id="robocal-sweep" data-updates="{self.updates}" data-sweep="{state}"></div>'

    def __call__(self, app: ViewerApp, update: PageUpdate) -> None:
        """The page hook: redraw the arcs that changed, publish the state."""
        self.redraw()

    def redraw(self) -> None:
        """Redraw what changed since the last call (the page thread calls it after each pose)."""
        with self._draw_lock:
            self._redraw()

    def _redraw(self) -> None:
        if self.app.server is None or not self._handles:
            return
        changed = False
        for a in self.arcs():
            key = (a.status, a.sampled_min, a.sampled_max)
            if self._drawn.get(a.name) == key:
                continue
            self._drawn[a.name] = key
            changed = True
            h = self._handles[a.name]["swept"]
            if not (math.isfinite(a.sampled_min) and math.isfinite(a.sampled_max)):
                h.visible = False
                continue
            hi = a.sampled_max if a.sampled_max > a.sampled_min else a.sampled_min + 1e-3
            axis = self.model.joint(a.name).axis
            h.points = polyline_segments(arc_points(axis, a.sampled_min, hi, 1.25 * self.radius_m))
            h.colors = np.tile(line_rgb(status_rgb(a.status)), (ARC_SEGMENTS, 2, 1))
            h.visible = True
        self.updates += 1
        if changed or self.updates == 1:
            assert self._state is not None
            self._state.content = self._state_html()




class SweepWebView:
    """The sweep workflow's view (:class:`robocal.workflows.sweep.job.SweepView`) on a web page.

    Poses the robot at the newest reading, shows the live status codes (rate-limited) and the final result;
    forwards every call to ``inner`` (the terminal's live table) too.

    Args:
        app: The started page (its model's joints are matched by name).
        inner: Another view to forward to, or None.
        period_s: Smallest interval between two status computations.
        threshold_rad: The sweep's not-swept threshold (None: the method's default).
        span_tolerance_rad: The sweep's span tolerance.
        clock: Monotonic clock, s.
    """

    def __init__(
        self,
        app: ViewerApp,
        inner: Any = None,
        *,
        period_s: float = 0.1,
        threshold_rad: float | None = None,
        span_tolerance_rad: float | None = None,
        clock: Callable[[], float] = time.monotonic,
    ) -> None:
        self.app = app
        self.overlay = SweepOverlay(app)
        self.inner = inner
        self.period_s = period_s
        self.threshold_rad = threshold_rad
        self.span_tolerance_rad = span_tolerance_rad
        self.clock = clock
        self._last = -math.inf
        self._index: dict[str, int] = {n: i for i, n in enumerate(app.joint_names)}
        self._current: dict[str, float] = {}
        self._t_s = 0.0
        self.result: SweepResult | None = None

    def _push(self, names: Sequence[str], values: FloatArray, t_s: float) -> None:
        raw = np.full(len(self.app.joint_names), np.nan)
        for n, v in zip(names, values, strict=True):
            i = self._index.get(n)
            if i is not None:
                raw[i] = v
        self.app.push(t_s, raw)

    def update(self, session: Any) -> None:
        """After every sample: pose the robot; every ``period_s`` the status codes as the report computes them."""
        if self.inner is not None:
            self.inner.update(session)
        cur = session.tracker.current
        self._current = dict(zip(session.names, (float(v) for v in cur), strict=True))
        self._t_s = float(session.t_s)
        self._push(session.names, cur, float(session.t_s))
        now = self.clock()
        if now - self._last < self.period_s:
            return
        self._last = now
        kwargs: dict[str, float] = {}
        if self.threshold_rad is not None:
            kwargs["threshold_rad"] = self.threshold_rad
        elif session.method == "one-sided":
            from ..core.sweep import DEFAULT_ONE_SIDED_THRESHOLD_RAD

            kwargs["threshold_rad"] = DEFAULT_ONE_SIDED_THRESHOLD_RAD
        if self.span_tolerance_rad is not None:
            kwargs["span_tolerance_rad"] = self.span_tolerance_rad
        result = session.result(**kwargs)
        self.overlay.set_result(result, self._current)

    def prompt(self, joint: str) -> None:
        """The direction check asks for a motion: shown on the page too."""
        if self.inner is not None:
            self.inner.prompt(joint)
        self.app.message(f"direction check: move {joint} toward its + limit")

    def direction_result(self, joint: str, verdict: int) -> None:
        """The direction check's verdict, shown on the page too."""
        if self.inner is not None:
            self.inner.direction_result(joint, verdict)
        text = {1: "direction ok", -1: "direction FLIPPED", 0: "direction not verified (no motion)"}[verdict]
        self.app.message(f"{joint}: {text}", "info" if verdict == 1 else "warning")

    def finish(self, result: SweepResult) -> None:
        """The final result: the arcs take the report's codes."""
        if self.inner is not None:
            self.inner.finish(result)
        self.result = result
        self.overlay.set_result(result, self._current)
        bad = [f"{j.name}: {j.status}" for j in result.joints if j.status != "ok"]
        self.app.message(
            "sweep finished: every joint ok" if not bad else "sweep finished: " + ", ".join(bad),
            "info" if not bad else "warning",
        )
        self.app.set_source_state("finished")
        if self._current:  # one more page update, so the page state carries the final messages too
            names = tuple(self._current)
            self._push(names, np.array([self._current[n] for n in names]), self._t_s)
        self.overlay.redraw()


def open_sweep_page(
    urdf: str | Any,
    *,
    inner: Any = None,
    host: str = "127.0.0.1",
    port: int = 8080,
    threshold_rad: float | None = None,
    span_tolerance_rad: float | None = None,
    title: str = "sweep",
) -> SweepWebView:
    """Load the URDF, start the page and return the sweep view that draws on it.

    Raises:
        CalibError: A URDF that does not load, a port in use, viser missing — before the sweep starts.
    """
    from .model import load_robot_model

    model = load_robot_model(urdf)
    app = ViewerApp(model, host=host, port=port, title=f"{title}: {model.name}", rate_hz=20.0).start()
    try:
        app.server.gui.main_panel.dock_right()  # the robot beside the joint table, not under it
        for w in model.warnings:
            app.message(w, "warning")
        app.set_source_state("running")
        return SweepWebView(app, inner, threshold_rad=threshold_rad, span_tolerance_rad=span_tolerance_rad)
    except BaseException:
        app.stop()
        raise
