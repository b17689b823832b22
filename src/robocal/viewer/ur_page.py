"""``robocal ur view``: the nominal and the calibrated UR chain side by side in the browser.

The page draws two UR arms posed at the same joint positions: the model's nominal geometry (URSim's DH, grey
blue) and the calibrated one (orange) — the controller's DH corrected the way ``robocal ur correct`` does,
so every link frame is where ur_description puts it (no far-away split-DH frames). ``tool0`` of both is
marked, and an arrow at the calibrated ``tool0`` shows the position error ``p_calibrated − p_nominal``
scaled up (×``arrow_scale``) so that millimetres can be seen next to a metre-long arm.

Numbers on the page:

* ``Δp at q``: ``‖p_calibrated(q) − p_nominal(q)‖`` at the sliders' joint positions, in metres formatted
  as ``robocal ur verify`` prints it (``.3g``), so ``robocal ur verify CAL.yaml --model MODEL --q Q`` prints
  the same string, ``CAL.yaml`` being what ``robocal ur correct`` writes for the same DH;
* ``max Δp``: the same error, maximised over ``robocal ur verify``'s random joint vectors (``--samples``,
  ``--seed``), computed by the same function: equal to what ``robocal ur verify CAL.yaml --model MODEL``
  prints.

The page state (JSON in ``#robocal-status[data-status]``) carries the joint positions, both ``tool0``
positions, the error vector and both numbers, for tests and scripts.
"""

from __future__ import annotations

import html
import json
import math
import socket
import tempfile
import threading
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from ..core.arrays import FloatArray
from ..core.dh import DHParameters, fk_dh
from ..core.ur import (
    JOINT_NAMES,
    UR_MODELS,
    correct_kinematics,
    deviation_from_nominal,
    fk_origins,
    nominal_dh,
)
from ..errors import UsageError
from ..workflows.ur import job as ur_wf
from ..workflows.ur import verify as ur_verify
from .scene import ServedPage, _viser, open_server, plain_lights, polyline_segments

__all__ = [
    "CALIBRATED_RGB",
    "NOMINAL_RGB",
    "UrComparison",
    "UrViewModel",
    "UrViewPage",
    "format_error_m",
    "parse_q",
]

NOMINAL_RGB = (90, 110, 150)
"""Colour of the nominal chain (grey blue)."""
CALIBRATED_RGB = (235, 120, 20)
"""Colour of the calibrated chain (orange)."""
ARROW_RGB = (200, 0, 160)
"""Colour of the scaled error arrow (magenta)."""
Q_LIMIT_RAD = 2.0 * math.pi
"""Sliders and ``--q`` span ``[−2π, 2π]``, the UR joints' range."""


def format_error_m(value_m: float) -> str:
    """A position error in metres, formatted exactly as ``robocal ur verify`` prints it (``.3g``)."""
    return f"{value_m:.3g}"


def parse_q(text: str | Sequence[float] | None) -> tuple[float, ...]:
    """Six joint positions (rad) from ``"q1,q2,…,q6"`` (or a sequence); None gives zeros.

    Raises:
        UsageError: Not six finite numbers within ``[−2π, 2π]``.
    """
    if text is None:
        return (0.0,) * 6
    if isinstance(text, str):
        parts = [p.strip() for p in text.replace(" ", ",").split(",") if p.strip()]
        try:
            values = [float(p) for p in parts]
        except ValueError:
            raise UsageError(f"--q {text!r}: expected six numbers in rad, e.g. 0,-1.57,1.57,0,0,0") from None
    else:
        values = [float(v) for v in text]
    if len(values) != 6:
        raise UsageError(f"--q: expected 6 joint positions (rad), got {len(values)}")
    for name, v in zip(JOINT_NAMES, values, strict=True):
        if not math.isfinite(v) or abs(v) > Q_LIMIT_RAD:
            raise UsageError(f"--q: {name} = {v} rad is not a finite number within [-2π, 2π]")
    return tuple(values)


@dataclass(frozen=True)
class UrComparison:
    """Both chains at one joint vector.

    Attributes:
        q_rad: The six joint positions, rad.
        frames_nominal_m: ``(7, 3)`` origins of base, the six joint frames (tool0 last) of the nominal arm.
        frames_calibrated_m: The same for the calibrated arm.
        error_m: ``(3,)`` ``p_calibrated − p_nominal`` of tool0, metres (base frame).
    """

    q_rad: tuple[float, ...]
    frames_nominal_m: FloatArray
    frames_calibrated_m: FloatArray
    error_m: FloatArray

    @property
    def error_norm_m(self) -> float:
        """``‖p_calibrated − p_nominal‖`` of tool0, metres."""
        return float(np.linalg.norm(self.error_m))


class UrViewModel:
    """The two arms of the page (pure numpy; no viser).

    Args:
        dh: The calibrated DH (from a file or a controller).
        model: UR model of the nominal geometry; None picks the model whose nominal lengths are closest.

    Raises:
        UsageError: Unknown model.
    """

    def __init__(self, dh: DHParameters, model: str | None = None) -> None:
        self.dh = dh
        self.calibrated = correct_kinematics(dh, "urdf")
        self.model = deviation_from_nominal(self.calibrated, model).model
        if self.model not in UR_MODELS:  # pragma: no cover - deviation_from_nominal refuses it first
            raise UsageError(f"unknown UR model {model!r}")
        self.nominal_dh = nominal_dh(self.model)
        self.nominal = correct_kinematics(self.nominal_dh, "urdf")
        self.reach_m = float(sum(abs(v) for v in UR_MODELS[self.model][:2])) + 0.3

    @staticmethod
    def _frames(xyz: FloatArray, rpy: FloatArray, q: FloatArray) -> FloatArray:
        pts = [np.zeros(3)]
        for k in range(1, 7):
            pts.append(fk_origins(xyz[:k], rpy[:k], q[:k])[:3, 3])
        return np.array(pts)

    def at(self, q_rad: Sequence[float]) -> UrComparison:
        """Both arms at ``q_rad`` (six values, rad).

        The calibrated tool0 comes from the corrected kinematics (as a URDF built from ``ur correct``'s
        YAML), the nominal one from the model's DH: the pair ``robocal ur verify`` compares.
        """
        q = np.asarray(q_rad, dtype=np.float64).reshape(6)
        cal = self._frames(self.calibrated.xyz_array(), self.calibrated.rpy_array(), q)
        nom = self._frames(self.nominal.xyz_array(), self.nominal.rpy_array(), q)
        T_file = fk_origins(self.calibrated.xyz_array(), self.calibrated.rpy_array(), q)
        T_dh = fk_dh(self.nominal_dh, q.reshape(1, 6))[0]
        err = np.asarray(T_file[:3, 3] - T_dh[:3, 3], dtype=np.float64)
        return UrComparison(tuple(float(v) for v in q), nom, cal, err)

    def verify_number(
        self, *, samples: int = 1000, seed: int = 0, q_rad: Sequence[float] | None = None
    ) -> float:
        """``robocal ur verify``'s ``max Δp (m)`` for ``ur correct``'s YAML of this DH against the nominal model.

        Runs the same two workflow functions as the CLI (:func:`robocal.workflows.ur.job.correct` into a temporary
        folder, then :func:`robocal.workflows.ur.job.verify`); nothing is left on disk.
        """
        with tempfile.TemporaryDirectory(prefix="robocal-ur-view-") as tmp:
            path = Path(tmp) / "calibration.yaml"
            ur_wf.correct(self.dh, path)
            q = None if q_rad is None else np.asarray(q_rad, dtype=np.float64).reshape(1, 6)
            report = ur_verify.verify(path, self.nominal_dh, samples=samples, seed=seed, q_rad=q)[0]
        return report.max_position_error_m


def _check_port_free(host: str, port: int) -> None:
    """Refuse a port another program listens on (viser would quietly move to the next one)."""
    if port == 0:
        return
    if not 0 < port < 65536:
        raise UsageError(f"--view-port {port}: expected 1..65535 (0: any free port)")
    family = socket.AF_INET6 if ":" in host else socket.AF_INET
    with socket.socket(family, socket.SOCK_STREAM) as s:
        s.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        try:
            s.bind((host, port))
        except OSError as exc:
            raise UsageError(f"cannot serve the page on {host}:{port}: {exc.strerror or exc}") from None


class UrViewPage(ServedPage):
    """The viser page of ``robocal ur view``.

    Args:
        view: The two arms.
        source: Where the calibrated DH came from (shown on the page).
        q_rad: Initial joint positions (rad).
        samples: Random joint vectors for the ``max Δp`` number (``ur verify --samples``).
        seed: Their seed (``ur verify --seed``).
        arrow_scale: Length of the drawn error arrow per metre of error.
        host: Interface to serve on.
        port: TCP port (0: any free port).
        allowed_origins: Other origins the page may be used from (``--allow-origin``, see :mod:`.access`).
    """

    def __init__(
        self,
        view: UrViewModel,
        *,
        source: str,
        q_rad: Sequence[float] | None = None,
        samples: int = 1000,
        seed: int = 0,
        arrow_scale: float = 100.0,
        host: str = "127.0.0.1",
        port: int = 8080,
        allowed_origins: Sequence[str] = (),
    ) -> None:
        if not (math.isfinite(arrow_scale) and arrow_scale > 0):
            raise UsageError(f"--arrow-scale {arrow_scale}: expected a positive number")
        self.view = view
        self.source = source
        self.q = parse_q(q_rad)
        self.samples = samples
        self.seed = seed
        self.arrow_scale = float(arrow_scale)
        self.host = host
        self.requested_port = port
        self.allowed_origins = tuple(allowed_origins)
        self.verify_m = view.verify_number(samples=samples, seed=seed)
        self.updates = 0
        self.side_by_side = True
        self.server: Any = None
        self.current: UrComparison = view.at(self.q)
        self._lock = threading.RLock()
        self._h: dict[str, Any] = {}

    # ------------------------------------------------------------------------------------------ lifecycle
    def start(self) -> UrViewPage:
        """Bind the port and build the page.

        Raises:
            UsageError: The port is in use.
            BackendNotAvailableError: viser is not installed.
        """
        viser = _viser("robocal ur view")
        _check_port_free(self.host, self.requested_port)
        self.server = open_server(viser, self.host, self.requested_port, self.allowed_origins)
        try:
            self._build()
        except BaseException:
            self.stop()
            raise
        return self

    # ------------------------------------------------------------------------------------------ state
    def set_q(self, q_rad: Sequence[float]) -> UrComparison:
        """Pose both arms at ``q_rad`` (also moves the sliders) and redraw; returns the comparison."""
        q = parse_q(q_rad)
        with self._lock:
            self.q = q
            if self._h:
                for slider, v in zip(self._h["sliders"], q, strict=True):
                    if abs(float(slider.value) - v) > 1e-12:
                        slider.value = v
            return self._redraw()

    def status(self) -> dict[str, Any]:
        """The page state (also in the page as JSON)."""
        c = self.current
        return {
            "view": "ur",
            "model": self.view.model,
            "source": self.source,
            "updates": self.updates,
            "q": list(c.q_rad),
            "tool0_nominal_m": [float(v) for v in c.frames_nominal_m[-1]],
            "tool0_calibrated_m": [float(v) for v in c.frames_calibrated_m[-1]],
            "error_vector_m": [float(v) for v in c.error_m],
            "error_m": c.error_norm_m,
            "error_text": format_error_m(c.error_norm_m),
            "verify": {
                "samples": self.samples,
                "seed": self.seed,
                "max_position_error_m": self.verify_m,
                "text": format_error_m(self.verify_m),
            },
            "arrow_scale": self.arrow_scale,
            "side_by_side": self.side_by_side,
        }

    # ------------------------------------------------------------------------------------------ drawing
    def _offset(self) -> FloatArray:
        return np.array([0.0, self.view.reach_m if self.side_by_side else 0.0, 0.0])

    def _build(self) -> None:
        server = self.server
        server.gui.configure_theme(control_width="large", dark_mode=False, show_logo=False)
        server.gui.main_panel.dock_right()  # the 3D view beside the panel, not under it
        server.scene.set_up_direction("+z")
        plain_lights(server)
        r = self.view.reach_m
        server.scene.add_grid(
            "/grid", width=4 * r, height=4 * r, cell_size=0.1, plane="xy", position=(0, r / 2, 0)
        )
        c = self.current
        off = self._offset()
        h = self._h
        h["nominal"] = server.scene.add_line_segments(
            "/nominal/links", polyline_segments(c.frames_nominal_m), NOMINAL_RGB, thickness=0.03
        )
        h["calibrated"] = server.scene.add_line_segments(
            "/calibrated/links", polyline_segments(c.frames_calibrated_m + off), CALIBRATED_RGB, thickness=0.03
        )
        h["nominal_tool0"] = server.scene.add_icosphere("/nominal/tool0", radius=0.035, color=NOMINAL_RGB)
        h["calibrated_tool0"] = server.scene.add_icosphere(
            "/calibrated/tool0", radius=0.035, color=CALIBRATED_RGB
        )
        server.scene.add_label("/nominal/label", "nominal", position=(0.0, 0.0, -0.05))
        h["cal_label"] = server.scene.add_label(
            "/calibrated/label", "calibrated", position=tuple(off - [0, 0, 0.05])
        )
        h["arrow"] = server.scene.add_arrows(
            "/error/arrow",
            np.zeros((1, 2, 3), dtype=np.float32),
            ARROW_RGB,
            shaft_radius=0.02,
            head_radius=0.05,
            head_length=0.08,
        )
        gui = server.gui
        gui.add_html(  # the source is a file name or a host: text, never markdown
            f"<b>UR {html.escape(self.view.model)}: nominal (grey blue) vs calibrated (orange)</b><br>"
            f"calibrated DH: {html.escape(self.source)}"
        )
        h["error"] = gui.add_text("Δp at q (m)", initial_value="", disabled=True)
        h["error_mm"] = gui.add_text("Δp at q (mm)", initial_value="", disabled=True)
        h["verify"] = gui.add_text(
            f"max Δp, {self.samples} samples (m)", initial_value=format_error_m(self.verify_m), disabled=True
        )
        gui.add_markdown(
            f"*max Δp* is what `robocal ur verify CAL.yaml --model {self.view.model} --samples {self.samples} "
            f"--seed {self.seed}` prints for the YAML `robocal ur correct` writes from this DH. "
            f"The magenta arrow is the tool0 error ×{self.arrow_scale:g}."
        )
        side = gui.add_checkbox("side by side", initial_value=True)

        def on_side(_: Any) -> None:
            with self._lock:
                self.side_by_side = bool(side.value)
                self._redraw()

        side.on_update(on_side)

        sliders = []
        with gui.add_folder("Joint positions (rad)"):
            for name, v in zip(JOINT_NAMES, self.q, strict=True):
                s = gui.add_slider(name, min=-Q_LIMIT_RAD, max=Q_LIMIT_RAD, step=0.001, initial_value=v)
                sliders.append(s)

        def on_slider(_: Any) -> None:
            with self._lock:
                self.q = tuple(float(s.value) for s in sliders)
                self._redraw()

        for s in sliders:
            s.on_update(on_slider)
        h["sliders"] = sliders
        h["status"] = gui.add_html(self._status_html())

        def on_connect(client: Any) -> None:
            client.camera.position = (1.25 * r, -0.45 * r, 0.8 * r)
            client.camera.look_at = (0.0, r / 2, 0.25)
            client.camera.up_direction = (0.0, 0.0, 1.0)

        server.on_client_connect(on_connect)

        self._redraw()

    def _status_html(self) -> str:
        state = html.escape(json.dumps(self.status(), separators=(",", ":")), quote=True)
        return (
            f'<div id="robocal-status" data-updates="{self.updates}" data-status="{state}" '
            'style="font-size:0.7em;color:#666"></div>'
        )

    def _redraw(self) -> UrComparison:
        with self._lock:
            c = self.view.at(self.q)
            self.current = c
            self.updates += 1
            if self.server is None or not self._h:
                return c
            h = self._h
            off = self._offset()
            tip = c.frames_calibrated_m[-1] + off
            arrow = np.array([[tip, tip + c.error_m * self.arrow_scale]], dtype=np.float32)
            with self.server.atomic():
                h["nominal"].points = polyline_segments(c.frames_nominal_m)
                h["calibrated"].points = polyline_segments(c.frames_calibrated_m + off)
                h["nominal_tool0"].position = tuple(float(v) for v in c.frames_nominal_m[-1])
                h["calibrated_tool0"].position = tuple(float(v) for v in tip)
                h["cal_label"].position = tuple(float(v) for v in off - np.array([0.0, 0.0, 0.05]))
                h["arrow"].points = arrow
                h["error"].value = format_error_m(c.error_norm_m)
                h["error_mm"].value = f"{c.error_norm_m * 1e3:.3f}"
                h["status"].content = self._status_html()
            return c
