"""The automatic hard-stop calibration on the model: the stop search drawn live in the browser.

``robocal sweep --auto … --view`` (and ``robocal demo --auto --view``) open a
:class:`~robocal.viewer.app.ViewerApp` on the robot's URDF and hand an :class:`AutoSweepWebView` to the run as
its live view (:class:`robocal.workflows.autocal.job.AutoView`: ``joint_start``, ``sample``, ``joint_done``).
It draws, with the arcs and colours of ``sweep --view`` (:mod:`robocal.viewer.sweep_page`):

* the robot posed at the newest reading of each joint (identity frame ``direction·raw``, as ``sweep --view``):
  the joint being searched moves, the joints already searched hold their park angles;
* per joint, the thin dark arc of its URDF limits and a thick arc: while the joint is searched, the range it
  travelled so far (``searching``, blue); once done, the range between its found stops (contact surfaces),
  coloured by its code; at the end, the codes of the sweep report the run wrote (``ok``, ``span_mismatch``,
  ``wrap_in_travel``, …) and, for a joint whose search failed, the auto report's code (``missing_stop``,
  ``blocked``, ``timeout``, …: crimson); a joint whose profile gives it no stop is never moved and stays grey
  (``not_searched``, drawn as ``not_swept``);
* a radial tick at each found stop, in the same colour.

The state is published in the page as JSON (``#robocal-autocal[data-autocal]``): the joint being searched, its
phase and side, the samples seen, and per joint its status, the found stops and the travelled range (rad).
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

from ..core.profile_auto import NOT_SEARCHED
from ..core.stop_search import StopSample
from ..core.sweep_result import SweepResult
from .app import PageUpdate, ViewerApp
from .sweep_page import (
    FAIL_RGB,
    LIVE_RGB,
    SweepOverlay,
    arc_points,
    json_num,
    line_rgb,
    status_json,
    status_rgb,
)

__all__ = ["AutoJointState", "AutoSweepWebView", "open_auto_sweep_page"]


@dataclass
class AutoJointState:
    """What the page knows of one joint of the auto run (identity frame, rad).

    Attributes:
        name: URDF joint name.
        status: ``waiting``, ``searching``, ``ok``, a report code or a failure code.
        reason: The failure's sentence ("" when none).
        seen_min: Smallest position read (NaN before a reading).
        seen_max: Largest position read.
        current: Newest position read.
        stop_minus: Found lower stop (contact surface), NaN when none.
        stop_plus: Found upper stop, NaN when none.
        samples: Readings seen.
        passed: The search passed (its arc spans the found stops; a failed one's spans the travelled range).
    """

    name: str
    status: str = "waiting"
    reason: str = ""
    seen_min: float = math.nan
    seen_max: float = math.nan
    current: float = math.nan
    stop_minus: float = math.nan
    stop_plus: float = math.nan
    samples: int = 0
    passed: bool = False

    def to_json(self) -> dict[str, Any]:
        """Plain data for the page state (NaN becomes None)."""
        return {
            **status_json(self.name, self.status),
            "reason": self.reason,
            "seen_min": json_num(self.seen_min),
            "seen_max": json_num(self.seen_max),
            "current": json_num(self.current),
            "stop_minus": json_num(self.stop_minus),
            "stop_plus": json_num(self.stop_plus),
            "samples": self.samples,
            "passed": self.passed,
        }


class AutoSweepWebView:
    """The auto run's live view (:class:`robocal.workflows.autocal.job.AutoView`) on a web page.

    Every call is forwarded to ``inner`` (the terminal's lines) too. Thread-safe: the run calls it from its
    thread, the page loop draws from its own.

    Args:
        app: The started page.
        inner: Another auto view to forward to, or None.
        joint_of: Driver joint name → URDF joint name (default: the same names).
        q_offset_rad: Subtracted from the driver's angles before they are drawn (a LeRobot servo's half turn:
            its joint frame counts ticks from 0, the arm's URDF has its zero at the middle pose).
        period_s: Smallest interval between two redraws of the arcs while a joint moves.
        clock: Monotonic clock, s.
    """

    def __init__(
        self,
        app: ViewerApp,
        inner: Any = None,
        *,
        joint_of: Mapping[str, str] | None = None,
        q_offset_rad: float = 0.0,
        period_s: float = 0.05,
        clock: Callable[[], float] = time.monotonic,
    ) -> None:
        self.app = app
        self.overlay = SweepOverlay(app)
        self.inner = inner
        self.joint_of = dict(joint_of) if joint_of is not None else None
        self.q_offset_rad = float(q_offset_rad)
        self.period_s = period_s
        self.clock = clock
        self._lock = threading.Lock()
        self._index = {n: i for i, n in enumerate(app.joint_names)}
        self._raw = np.full(len(app.joint_names), np.nan)
        self.joints: dict[str, AutoJointState] = {n: AutoJointState(n) for n in app.joint_names}
        self.active: str | None = None
        self.phase = ""
        self.side = ""
        self.samples = 0
        self.finished = False
        self.result: SweepResult | None = None
        self._last = -math.inf
        self._t_s = 0.0
        self._ticks: dict[str, Any] = {}
        self._ticks_drawn: dict[str, tuple[str, float, float]] = {}
        self._state_el: Any = None
        self._state_sent = ""
        self._send_lock = threading.Lock()
        self._build()
        app.add_hook(self._draw)

    # --------------------------------------------------------------------------------------- AutoView
    def _joint(self, name: str) -> str | None:
        j = self.joint_of.get(name) if self.joint_of is not None else name
        return j if j in self._index else None

    def joint_start(self, name: str, cap_nm: float, speed_rad_s: float) -> None:
        """A joint's search begins: it turns ``searching`` and its travelled range starts empty."""
        if self.inner is not None:
            self.inner.joint_start(name, cap_nm, speed_rad_s)
        j = self._joint(name)
        with self._lock:
            self.active = j
            self.phase, self.side = "start", ""
            if j is not None:
                self.joints[j] = AutoJointState(j, "searching", current=self.joints[j].current)
        self.app.message(
            f"{name}: searching its stops at {math.degrees(speed_rad_s):.0f}°/s, cap {cap_nm:.2f} N·m"
        )
        self._publish(force=True)

    def sample(self, name: str, phase: str, side: str, sample: StopSample) -> None:
        """One reading: pose the joint, widen its travelled range (the arcs at most every ``period_s``)."""
        if self.inner is not None:
            self.inner.sample(name, phase, side, sample)
        j = self._joint(name)
        if j is None:
            return
        with self._lock:
            self.phase, self.side = phase, side
            self.samples += 1
            st = self.joints[j]
            st.samples += 1
            if sample.ok and math.isfinite(sample.q_rad):
                q = float(sample.q_rad) - self.q_offset_rad
                st.current = q
                st.seen_min = q if not math.isfinite(st.seen_min) else min(st.seen_min, q)
                st.seen_max = q if not math.isfinite(st.seen_max) else max(st.seen_max, q)
                self._raw[self._index[j]] = q
            self._t_s = float(sample.t_s)
            raw = self._raw.copy()
        self.app.push(self._t_s, raw)
        self._publish()

    def joint_done(self, outcome: Any) -> None:
        """A joint finished: its arc spans the found stops, coloured ``ok`` or by its failure code."""
        if self.inner is not None:
            self.inner.joint_done(outcome)
        j = self._joint(outcome.name)
        st = outcome.stops
        if j is not None:
            self._record(j, outcome)
        if outcome.ok:
            span = f", span {math.degrees(st.span_rad):.2f}°" if math.isfinite(st.span_rad) else ""
            self.app.message(f"{outcome.name}: ok{span}")
        else:
            self.app.message(f"{outcome.name}: FAILED {st.code}: {st.reason}", "warning")
        self._publish(force=True)

    # --------------------------------------------------------------------------------------- the end
    def finish(self, auto: Any, result: SweepResult | None = None) -> None:
        """The run is over: the arcs take the report's codes (``result``) or the failure codes (``auto``).

        Args:
            auto: The :class:`~robocal.workflows.autocal.job.AutoCalResult`.
            result: The sweep result of the joints that passed (None when nothing was computed).
        """
        for o in auto.joints:
            j = self._joint(o.name)
            if j is not None and self.joints[j].status in ("waiting", "searching"):
                self._record(j, o)
        with self._lock:
            if result is not None:
                self.result = result
                for r in result.joints:
                    j = self._joint(r.name)
                    if j is not None and self.joints[j].status not in ("waiting", "searching"):
                        self.joints[j].status = r.status
            self.active = None
            self.finished = True
        bad = [f"{s.name}: {s.status}" for s in self.joints.values() if s.status not in ("ok", "waiting")]
        self.app.message(
            "auto-calibration finished: every joint ok"
            if not bad
            else "auto-calibration finished: " + ", ".join(bad),
            "info" if not bad else "warning",
        )
        self.app.set_source_state("finished")
        self._publish(force=True)
        self._send_state()  # the final state goes out now, whatever the page loop is doing
        with self._lock:
            raw = self._raw.copy()
        self.app.push(self._t_s, raw)  # one more page update: the final state reaches the page

    def _record(self, j: str, outcome: Any) -> None:
        """Record a joint's outcome: its code, reason and found stops."""
        st = outcome.stops
        with self._lock:
            s = self.joints[j]
            s.status, s.reason, s.passed = st.code, st.reason, bool(outcome.ok)
            off = self.q_offset_rad
            s.stop_minus = st.lower.q_stop_rad - off if st.lower is not None else math.nan
            s.stop_plus = st.upper.q_stop_rad - off if st.upper is not None else math.nan
            if self.active == j:
                self.active = None

    def failed(self, text: str) -> None:
        """The run was aborted (device fault, Ctrl-C): say so on the page."""
        with self._lock:
            if self.active is not None:
                self.joints[self.active].status = "aborted"
            self.active = None
            self.finished = True
        self.app.set_source_state("failed", text)
        self._publish(force=True)
        self._send_state()
        with self._lock:
            raw = self._raw.copy()
        self.app.push(self._t_s, raw)

    # --------------------------------------------------------------------------------------- page state
    def status(self) -> dict[str, Any]:
        """The auto view's page state."""
        with self._lock:
            return {
                "active": self.active,
                "phase": self.phase,
                "side": self.side,
                "samples": self.samples,
                "finished": self.finished,
                "joints": [self.joints[n].to_json() for n in self.app.joint_names],
            }

    def _publish(self, *, force: bool = False) -> None:
        """Hand the arcs to the overlay (rate-limited unless ``force``); drawn at the next page update."""
        now = self.clock()
        if not force and now - self._last < self.period_s:
            return
        self._last = now
        with self._lock:
            shown = [s for s in self.joints.values() if s.status != "waiting"]
            lo: dict[str, float] = {}
            hi: dict[str, float] = {}
            for s in shown:
                lo[s.name], hi[s.name] = self._arc_range(s)
            self.overlay.set_ranges(
                lo, hi, {s.name: s.current for s in shown}, {s.name: s.status for s in shown}
            )

    def _arc_range(self, s: AutoJointState) -> tuple[float, float]:
        """The thick arc: the travelled range while searching or failed, the found stops once found.

        A one-sided joint's other end is placed the URDF span away (as the written result does).
        """
        a, b = s.stop_minus, s.stop_plus
        if not s.passed or not (math.isfinite(a) or math.isfinite(b)):
            return s.seen_min, s.seen_max
        j = self.app.model.joint(s.name)
        span = float(j.upper - j.lower) if math.isfinite(j.upper - j.lower) else math.nan
        if not math.isfinite(a):
            a = b - span if math.isfinite(span) else s.seen_min
        if not math.isfinite(b):
            b = a + span if math.isfinite(span) else s.seen_max
        return a, b

    # --------------------------------------------------------------------------------------- drawing
    def _build(self) -> None:
        server = self.app.server
        if server is None:
            return
        for n in self.app.joint_names:
            self._ticks[n] = server.scene.add_line_segments(
                f"{self.overlay._joint_path(n)}/stops",
                np.zeros((2, 2, 3), dtype=np.float32),
                np.tile(
                    line_rgb(status_rgb("ok")), (2, 2, 1)
                ),  # per vertex from the start (see SweepOverlay)
                thickness=0.25 * self.overlay.radius_m,
                visible=False,
            )
        legend = (
            f'<span style="color:rgb{LIVE_RGB["searching"]}">■</span> searching (range travelled so far) · '
            f'<span style="color:rgb{FAIL_RGB}">■</span> search failed (missing_stop, blocked, timeout, …) · '
            f'<span style="color:rgb{status_rgb(NOT_SEARCHED)}">■</span> not_searched (no stop in the profile) · '
            "ticks: found stops"
        )
        server.gui.add_html(f'<div style="font-size:0.8em">{legend}</div>')
        self._state_el = server.gui.add_html(self._state_html())

    def _state_html(self) -> str:
        state = html.escape(json.dumps(self.status(), separators=(",", ":")), quote=True)
        return f'<div id="robocal-autocal" data-autocal="{state}"></div>'

    def _draw(self, app: ViewerApp, update: PageUpdate) -> None:
        """Page hook: the found-stop ticks that changed, the page state when it changed."""
        r0, r1 = 1.0 * self.overlay.radius_m, 1.6 * self.overlay.radius_m
        with self._lock:
            items = [(s.name, s.status, s.stop_minus, s.stop_plus) for s in self.joints.values()]
        for name, status, a, b in items:
            key = (status, a, b)
            if self._ticks_drawn.get(name) == key or name not in self._ticks:
                continue
            self._ticks_drawn[name] = key
            h = self._ticks[name]
            stops = [x for x in (a, b) if math.isfinite(x)]
            if not stops:
                h.visible = False
                continue
            axis = self.app.model.joint(name).axis
            segs = [
                np.stack([arc_points(axis, x, x, r0, 1)[0], arc_points(axis, x, x, r1, 1)[0]]) for x in stops
            ]
            h.points = np.asarray(segs, dtype=np.float32)
            h.colors = np.tile(line_rgb(status_rgb(status)), (len(stops), 2, 1))
            h.visible = True
        self._send_state()

    def _send_state(self) -> None:
        """Send the page state if it changed (page thread and the run's end; the newest state is sent last)."""
        with self._send_lock:
            html_now = self._state_html()
            if html_now != self._state_sent and self._state_el is not None:
                self._state_el.content = html_now
                self._state_sent = html_now


def open_auto_sweep_page(
    urdf: str | Any,
    *,
    inner: Any = None,
    joint_of: Mapping[str, str] | None = None,
    q_offset_rad: float = 0.0,
    host: str = "127.0.0.1",
    port: int = 8080,
    title: str = "sweep --auto",
    note: Sequence[str] = (),
) -> AutoSweepWebView:
    """Load the URDF, start the page and return the auto view that draws on it.

    Raises:
        CalibError: A URDF that does not load, a port in use, viser missing — before anything moves.
    """
    from .model import load_robot_model

    model = load_robot_model(urdf)
    app = ViewerApp(model, host=host, port=port, title=f"{title}: {model.name}", rate_hz=20.0).start()
    try:
        app.server.gui.main_panel.dock_right()
        for w in model.warnings:
            app.message(w, "warning")
        for line in note:
            app.message(line)
        app.set_source_state("running")
        return AutoSweepWebView(app, inner, joint_of=joint_of, q_offset_rad=q_offset_rad)
    except BaseException:
        app.stop()
        raise
