"""The viser web page: the robot, its ghost, the joint panel, the replay controls, the page loop.

See :mod:`robocal.viewer` for the public API and the page state a browser test can read.
"""

from __future__ import annotations

import html
import json
import math
import threading
import time
from collections.abc import Callable, Sequence
from typing import Any

import numpy as np
import numpy.typing as npt

from ..backends.bus_transaction import start_signal_free
from ..errors import UsageError
from .latest import Frame, LatestFrame, next_tick
from .mapping import JointMapper
from .model import RobotModel
from .scene import (
    GHOST_OPACITY,
    GHOST_RGB,
    OUTSIDE_RGB,
    TABLE_HZ,
    JointReadout,
    PageUpdate,
    ReplayControl,
    ServedPage,
    _Robot,
    _viser,
    check_port_free,
    joint_table_html,
    open_server,
    plain_lights,
    stop_thread,
)

__all__ = [
    "GHOST_RGB",
    "OUTSIDE_RGB",
    "JointReadout",
    "PageUpdate",
    "ReplayControl",
    "ViewerApp",
    "check_port_free",
    "plain_lights",
]


class ViewerApp(ServedPage):
    """A local web page showing ``model`` posed by the newest joint frame.

    Args:
        model: The robot.
        calibration: Raw → joint map of the robot (None: raw values are joint positions).
        compare: Raw → joint map of the ghost (None: no ghost).
        host: Interface to serve on.
        port: TCP port (0: any free port).
        rate_hz: Page updates per second (the page loop).
        clock: Monotonic clock, s (injected by tests).
        title: Shown at the top of the panel (as text, never markdown or HTML).
        raw_unit: Unit of the raw values, shown in the panel (``rad``, ``ticks``).
        allowed_origins: Other origins the page may be used from (``--allow-origin``, see :mod:`.access`).
    """

    def __init__(
        self,
        model: RobotModel,
        *,
        calibration: JointMapper | None = None,
        compare: JointMapper | None = None,
        host: str = "127.0.0.1",
        port: int = 8080,
        rate_hz: float = 30.0,
        clock: Callable[[], float] = time.monotonic,
        title: str = "",
        raw_unit: str = "rad",
        allowed_origins: Sequence[str] = (),
    ) -> None:
        if not (math.isfinite(rate_hz) and 0 < rate_hz <= 240):
            raise UsageError(f"--rate {rate_hz}: expected 0 < rate <= 240 page updates per second")
        self.model = model
        self.joint_names = model.actuated
        self.calibration = calibration or JointMapper(self.joint_names, None, "none")
        self.compare = compare
        self.host = host
        self.requested_port = port
        self.rate_hz = rate_hz
        self.clock = clock
        self.title = title or model.name
        self.raw_unit = raw_unit
        self.allowed_origins = tuple(allowed_origins)
        self.slot = LatestFrame(clock)
        self.updates = 0
        """Page updates made (frames shown)."""
        self.last_latency_s = math.nan
        self.max_latency_s = 0.0
        self.last_update: PageUpdate | None = None
        self.messages: list[tuple[str, str]] = []
        """``(level, text)`` shown on the page: ``info``, ``warning`` or ``error``."""
        self.source_state = "waiting"
        """``waiting``, ``running``, ``finished`` or ``failed``."""
        self._hooks: list[Callable[[ViewerApp, PageUpdate], None]] = []
        self._lock = threading.RLock()
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        self._replay: ReplayControl | None = None
        self._replay_gui: dict[str, Any] = {}
        self.server: Any = None
        self.robot: _Robot | None = None
        self.ghost: _Robot | None = None
        self._panel: Any = None
        self._status_el: Any = None
        self._frame_el: Any = None
        self._status_drawn_s = -math.inf
        self._status_pending = False
        self._table_drawn_s = -math.inf
        self._banner: Any = None
        self.title_el: Any = None
        """The title at the top of the panel (an HTML element holding the escaped title: text only)."""
        self._outside_now = np.zeros(len(self.joint_names), dtype=bool)

    # ------------------------------------------------------------------------------------------- lifecycle
    def start(self, *, loop: bool = True) -> ViewerApp:
        """Bind the port, build the scene and the panel, start the page loop.

        Args:
            loop: Start the page loop thread (tests pass False and call :meth:`step` themselves).

        Raises:
            UsageError: The port is in use.
            BackendNotAvailableError: viser is not installed.
        """
        viser = _viser()
        check_port_free(self.host, self.requested_port)
        server = open_server(viser, self.host, self.requested_port, self.allowed_origins)
        self.server = server
        try:
            self._build()
        except BaseException:
            server.stop()
            raise
        if loop:
            thread = threading.Thread(target=self._loop, name="robocal-view-page", daemon=True)
            self._thread = start_signal_free(thread)  # signals go to the main thread
        return self

    def stop(self) -> None:
        """Stop the page loop and the server (idempotent)."""
        stop_thread(self._stop, self._thread)
        self._thread = None
        super().stop()

    def wait(self, timeout_s: float | None = None) -> bool:
        """Block until :meth:`stop` (True) or ``timeout_s`` (False)."""
        return self._stop.wait(timeout_s)

    # ------------------------------------------------------------------------------------------- producer API
    def push(self, t_s: float, raw: npt.ArrayLike) -> None:
        """Hand the newest frame to the page (any thread; replaces an unshown one, never queues).

        Args:
            t_s: Source time stamp, s.
            raw: Shape ``(N,)`` raw values in :attr:`joint_names` order (NaN: not read).
        """
        self.slot.put(t_s, raw)

    def add_hook(self, hook: Callable[[ViewerApp, PageUpdate], None]) -> None:
        """Call ``hook(app, update)`` after every page update (overlays: arcs, arrows, labels).

        Hooks run on the page thread inside the same ``server.atomic()`` block as the robot, so their scene
        changes reach the browser together with the pose.
        """
        self._hooks.append(hook)

    def message(self, text: str, level: str = "info") -> None:
        """Show ``text`` on the page (``info``, ``warning`` or ``error``); the newest few are kept."""
        with self._lock:
            self.messages = [*self.messages[-4:], (level, text)]
        self._render_banner()

    def set_source_state(self, state: str, text: str = "") -> None:
        """Record the source's state (``running``, ``finished``, ``failed``) and optionally show ``text``."""
        self.source_state = state
        if text:
            self.message(text, "error" if state == "failed" else "info")
        else:
            self._render_banner()

    def attach_replay(self, control: ReplayControl) -> None:
        """Add a time slider and play/pause to the page, driving ``control``."""
        self._replay = control
        if self.server is not None:
            self._build_replay()

    # ------------------------------------------------------------------------------------------- page loop
    def _loop(self) -> None:
        period = 1.0 / self.rate_hz
        next_t = time.monotonic()
        while not self._stop.is_set():
            try:
                self.tick()
            except Exception as exc:  # a hook or the server failed: show it, keep serving
                self.message(f"page update failed: {type(exc).__name__}: {exc}", "error")
                self._stop.wait(1.0)
            next_t, delay = next_tick(next_t, time.monotonic(), period)
            self._stop.wait(delay)

    def readouts(self, frame: Frame) -> PageUpdate:
        """Compute (without drawing) what ``frame`` shows."""
        q = self.calibration.to_joint(frame.raw)
        qc = self.compare.to_joint(frame.raw) if self.compare is not None else None
        outside = self.model.outside_limits(q)
        poses, local = self.model.poses(q)
        ghost, ghost_local = self.model.poses(qc) if qc is not None else (None, None)
        joints = tuple(
            JointReadout(
                name,
                float(frame.raw[i]),
                float(q[i]),
                float(qc[i]) if qc is not None else math.nan,
                float(self.model.lower[i]),
                float(self.model.upper[i]),
                bool(outside[i]),
            )
            for i, name in enumerate(self.joint_names)
        )
        return PageUpdate(frame, q, qc, outside, poses, ghost, joints, local, ghost_local)

    def step(self) -> bool:
        """One page update: take the newest frame (if any new), pose the robot and ghost, refresh the panel.

        The page state (``#robocal-status``) is sent with every update; the page loop runs :meth:`tick` instead.

        Returns:
            True when a new frame was shown.
        """
        return self._update(throttle=False)

    def tick(self) -> bool:
        """One iteration of the page loop: :meth:`step` with the page state sent at most :data:`TABLE_HZ` a second.

        The page state also goes out when a joint crosses a limit, and, without a new frame, once a state newer
        than the page's is due. Per update the page gets the pose and a small counter (``#robocal-frame``).

        Returns:
            True when a new frame was shown.
        """
        if self._update(throttle=True):
            return True
        if self._status_pending:
            self._render_status(force=False, throttle=True)
        return False

    def _update(self, *, throttle: bool) -> bool:
        frame = self.slot.take()
        if frame is None:
            return False
        update = self.readouts(frame)
        latency = self.clock() - frame.put_s
        with self._lock:
            self.last_latency_s = latency
            self.max_latency_s = max(self.max_latency_s, latency)
            self.updates += 1
            self.last_update = update
        if self.server is None:
            return True
        with self.server.atomic():
            assert self.robot is not None
            self.robot.pose(update.local)
            changed = np.flatnonzero(update.outside != self._outside_now)
            for i in changed:
                link = self.model.child_link(self.joint_names[i])
                self.robot.tint(link, OUTSIDE_RGB if update.outside[i] else None)
            self._outside_now = update.outside.copy()
            if self.ghost is not None and update.ghost_local is not None:
                self.ghost.pose(update.ghost_local)
            self._render_panel(update, force_table=changed.size > 0, throttle=throttle)
            self._sync_replay()
            for hook in self._hooks:
                hook(self, update)
        return True

    # ------------------------------------------------------------------------------------------- page state
    def status(self) -> dict[str, Any]:
        """The page's state as plain data (also embedded in the page as JSON, see :mod:`robocal.viewer`)."""
        with self._lock:
            u = self.last_update
            out: dict[str, Any] = {
                "robot": self.model.name,
                "updates": self.updates,
                "frames_in": self.slot.frames_in,
                "frames_dropped": self.slot.dropped,
                "latency_s": None if math.isnan(self.last_latency_s) else self.last_latency_s,
                "source": self.source_state,
                "calibration": self.calibration.label,
                "compare": self.compare.label if self.compare is not None else None,
                "t_s": u.frame.t_s if u is not None else None,
                "messages": [{"level": lv, "text": tx} for lv, tx in self.messages],
                "joints": [],
            }
            if self._replay is not None:
                out["replay"] = {
                    "playing": self._replay.playing,
                    "position_s": self._replay.position_s,
                    "start_s": self._replay.t_start_s,
                    "end_s": self._replay.t_end_s,
                }
            if u is not None:
                out["joints"] = [
                    {
                        "name": j.name,
                        "raw": None if math.isnan(j.raw) else j.raw,
                        "q": None if math.isnan(j.q) else j.q,
                        "q_compare": None if math.isnan(j.q_compare) else j.q_compare,
                        "lower": j.lower if math.isfinite(j.lower) else None,
                        "upper": j.upper if math.isfinite(j.upper) else None,
                        "outside": j.outside,
                        "color": "red" if j.outside else "normal",
                    }
                    for j in u.joints
                ]
        return out

    # ------------------------------------------------------------------------------------------- building
    def _build(self) -> None:
        server = self.server
        server.gui.configure_theme(control_width="large", dark_mode=False, show_logo=False)
        server.scene.set_up_direction("+z")
        plain_lights(server)
        server.scene.add_grid("/grid", width=2.0, height=2.0, cell_size=0.1, plane="xy")
        self.robot = _Robot(server, self.model, "/robot", rgb=None, opacity=None)
        if self.compare is not None:
            self.ghost = _Robot(server, self.model, "/ghost", rgb=GHOST_RGB, opacity=GHOST_OPACITY)
        self.title_el = server.gui.add_html(f"<b>{html.escape(self.title)}</b>")  # text: never markdown
        self._banner = server.gui.add_html(self._banner_html())
        if self._replay is not None:
            self._build_replay()
        if self.ghost is not None:
            toggle = server.gui.add_checkbox("Show ghost (--compare)", initial_value=True)

            def show_ghost(_: Any) -> None:
                if self.ghost is not None:
                    self.ghost.set_visible(bool(toggle.value))

            toggle.on_update(show_ghost)

        self._panel = server.gui.add_html(self._table_html(None))
        self._frame_el = server.gui.add_html(self._frame_html())
        self._status_el = server.gui.add_html(self._status_html())
        world, rest = self.model.poses(np.zeros(len(self.joint_names)))
        pts = np.array([T[:3, 3] for T in world.values()])
        centre = 0.5 * (pts.min(axis=0) + pts.max(axis=0))
        size = max(0.3, float(np.linalg.norm(pts.max(axis=0) - pts.min(axis=0))))
        server.initial_camera.look_at = tuple(float(x) for x in centre)
        server.initial_camera.position = tuple(float(x) for x in centre + np.array([1.6, -2.0, 1.1]) * size)
        self.robot.pose(rest)
        if self.ghost is not None:
            self.ghost.pose(rest)

    def _build_replay(self) -> None:
        control = self._replay
        if control is None or self._replay_gui or self.server is None:
            return
        gui = self.server.gui
        folder = gui.add_folder("Replay")
        with folder:
            lo, hi = control.t_start_s, control.t_end_s
            if not hi > lo:
                hi = lo + 1e-3
            slider = gui.add_slider("time (s)", min=lo, max=hi, step=(hi - lo) / 1000.0, initial_value=lo)
            button = gui.add_button("Pause" if control.playing else "Play")

        def seek(event: Any) -> None:
            if event.client is None:  # our own sync of the slider, not the user's drag
                return
            control.seek(float(slider.value))

        def play_pause(_: Any) -> None:
            if control.playing:
                control.pause()
            else:
                control.play()
            button.label = "Pause" if control.playing else "Play"

        slider.on_update(seek)
        button.on_click(play_pause)

        self._replay_gui = {"slider": slider, "button": button}

    def _sync_replay(self) -> None:
        control = self._replay
        if control is None or not self._replay_gui:
            return
        slider = self._replay_gui["slider"]
        t = min(max(control.position_s, slider.min), slider.max)
        if abs(float(slider.value) - t) > 1e-9:
            slider.value = t
        label = "Pause" if control.playing else "Play"
        if self._replay_gui["button"].label != label:
            self._replay_gui["button"].label = label

    def _banner_html(self) -> str:
        colours = {"info": "#335", "warning": "#a60", "error": "#c00"}
        with self._lock:
            rows = "".join(
                f'<div class="robocal-msg robocal-{lv}" style="color:{colours.get(lv, "#333")}">'
                f"{html.escape(tx)}</div>"
                for lv, tx in self.messages
            )
        return f'<div id="robocal-messages" data-source="{self.source_state}">{rows}</div>'

    def _render_banner(self) -> None:
        self._status_pending = True  # the page state carries the messages and the source state too
        if self._banner is not None:
            self._banner.content = self._banner_html()

    def _table_html(self, update: PageUpdate | None) -> str:
        return joint_table_html(self.model, update, ghost=self.compare is not None, raw_unit=self.raw_unit)

    def _status_html(self) -> str:
        status = html.escape(json.dumps(self.status(), separators=(",", ":")), quote=True)
        return f'<div id="robocal-status" data-updates="{self.updates}" data-status="{status}"></div>'

    def _frame_html(self) -> str:
        return (
            f'<div id="robocal-frame" data-updates="{self.updates}" style="font-size:0.7em;color:#666">'
            f"updates {self.updates} · dropped {self.slot.dropped}</div>"
        )

    def _render_status(self, *, force: bool, throttle: bool) -> None:
        """The page state (JSON): when ``force`` or not ``throttle``, else at most :data:`TABLE_HZ` times a second."""
        now = self.clock()
        if self._status_el is None:
            return
        if force or not throttle or now - self._status_drawn_s >= 1.0 / TABLE_HZ:
            self._status_pending = False
            self._status_drawn_s = now
            self._status_el.content = self._status_html()
        else:
            self._status_pending = True

    def _render_panel(self, update: PageUpdate, *, force_table: bool = False, throttle: bool = False) -> None:
        """Per update a small counter; the page state and the joint table at most :data:`TABLE_HZ` times a second.

        Both are also drawn when a joint crosses a limit, and the page state when the loop is idle with a newer
        state than the page has; the page's work per update stays small (a GPU-less browser's is the limit).
        """
        if self._frame_el is not None:
            self._frame_el.content = self._frame_html()
        self._render_status(force=force_table, throttle=throttle)
        if self._panel is None:
            return
        now = self.clock()
        if force_table or now - self._table_drawn_s >= 1.0 / TABLE_HZ:
            self._panel.content = self._table_html(update)
            self._table_drawn_s = now
