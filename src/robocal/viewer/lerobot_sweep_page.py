"""``robocal lerobot calibrate … --view``: the LeRobot arm's recorded ranges drawn on its model in the browser.

The arcs and colours are those of :mod:`robocal.viewer.sweep_page` (the status codes of the sweep report).
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Mapping, Sequence
from typing import Any

import numpy as np
import numpy.typing as npt

from ..core.arrays import FloatArray
from ..core.sweep_result import SweepResult
from .app import ViewerApp
from .sweep_page import SweepOverlay

__all__ = [
    "LeRobotSweepWebView",
    "lerobot_shapes_urdf",
    "open_lerobot_auto_page",
    "open_lerobot_sweep_page",
    "urdf_joint_of_motor",
]



TICKS_PER_TURN = 4096
"""Feetech STS3215 / Dynamixel XL330 resolution: the LeRobot arms' ticks per turn."""


class LeRobotSweepWebView:
    """``robocal lerobot calibrate --view``: the range-of-motion recording drawn on the arm.

    LeRobot's calibration first homes every motor so that the middle pose reads half a turn (2048 ticks), then
    records each motor's min and max while the operator moves every joint through its range. The arm's URDF
    (``so101_new_calib`` convention) has its zero at that middle pose, so ``(ticks − 2048)·2π/4096`` is the joint
    angle, and the recorded range is compared with the URDF limits by :func:`robocal.core.sweep.analyse_sweep`
    — the codes of ``robocal sweep``'s report (``not_swept``, ``span_mismatch``, ``no_overlap``, …).

    Call it with each :class:`robocal.workflows.lerobot.SweepView` (it is an ``on_sweep`` callback); it forwards
    to ``inner`` (the terminal's table) too.

    Args:
        app: The started page on the arm's URDF.
        joint_of: Motor name → URDF joint name (motors without one are not drawn).
        inner: Another ``on_sweep`` callback, or None.
        period_s: Smallest interval between two status computations.
        clock: Monotonic clock, s.
    """

    def __init__(
        self,
        app: ViewerApp,
        joint_of: Mapping[str, str],
        inner: Callable[[Any], None] | None = None,
        *,
        period_s: float = 0.1,
        clock: Callable[[], float] = time.monotonic,
    ) -> None:
        self.app = app
        self.overlay = SweepOverlay(app)
        self.joint_of = dict(joint_of)
        self.inner = inner
        self.period_s = period_s
        self.clock = clock
        self._last = -math.inf
        self._index = {n: i for i, n in enumerate(app.joint_names)}
        self.result: SweepResult | None = None

    @staticmethod
    def to_rad(ticks: Sequence[int] | npt.ArrayLike) -> FloatArray:
        """Ticks about the half turn → rad."""
        return (np.asarray(ticks, dtype=np.float64) - TICKS_PER_TURN / 2) * (2.0 * math.pi / TICKS_PER_TURN)

    def __call__(self, view: Any, *, final: bool = False) -> None:
        """One reading of the range recording (``SweepView``: names, present, minimum, maximum in ticks)."""
        if self.inner is not None and not final:
            self.inner(view)
        motors = [m for m in view.names if m in self.joint_of]
        sel = [i for i, m in enumerate(view.names) if m in self.joint_of]
        joints = [self.joint_of[m] for m in motors]
        present = self.to_rad([view.present[i] for i in sel])
        raw = np.full(len(self.app.joint_names), np.nan)
        for j, v in zip(joints, present, strict=True):
            if j in self._index:
                raw[self._index[j]] = v
        self.app.push(float(view.step), raw)
        now = self.clock()
        if not final and now - self._last < self.period_s:
            return
        self._last = now
        from ..core.sweep import analyse_sweep

        model = self.app.model
        known = [(j, k) for k, j in enumerate(joints) if j in self._index]
        names = [j for j, _ in known]
        lo = [model.joint(j).lower for j in names]
        hi = [model.joint(j).upper for j in names]
        s_min = self.to_rad([view.minimum[sel[k]] for _, k in known])
        s_max = self.to_rad([view.maximum[sel[k]] for _, k in known])
        result = analyse_sweep(names, np.ones(len(names)), lo, hi, s_min, s_max, wraps=False)
        self.result = result
        self.overlay.set_result(result, {j: float(present[k]) for j, k in known})
        if final:
            self.overlay.redraw()


def lerobot_shapes_urdf(robot: str) -> Any:
    """The URDF drawn for a LeRobot arm: SO-100/SO-101 simple shapes, Koch's URDF (its meshes fall back)."""
    from importlib import resources
    from pathlib import Path

    name = "koch.urdf" if robot.startswith("koch") else "so101_shapes.urdf"
    return Path(str(resources.files("robocal") / "data" / name))


def open_lerobot_sweep_page(
    robot: str,
    motor_names: Sequence[str],
    *,
    inner: Callable[[Any], None] | None = None,
    host: str = "127.0.0.1",
    port: int = 8080,
) -> LeRobotSweepWebView:
    """Start the page for ``robocal lerobot calibrate --view`` and return its ``on_sweep`` callback.

    Motors map to URDF joints by name (SO-100/SO-101), else in order (Koch: ``joint1`` … in motor order).

    Raises:
        CalibError: The URDF does not load, a port in use, viser missing.
    """
    from .model import load_robot_model

    model = load_robot_model(lerobot_shapes_urdf(robot))
    joint_of = urdf_joint_of_motor(model.actuated, motor_names)
    app = ViewerApp(model, host=host, port=port, title=f"lerobot calibrate: {robot}", rate_hz=20.0).start()
    try:
        app.server.gui.main_panel.dock_right()
        for w in model.warnings:
            app.message(w, "warning")
        app.message("move every joint through its whole range; the arcs show the recorded range")
        app.set_source_state("running")
        return LeRobotSweepWebView(app, joint_of, inner)
    except BaseException:
        app.stop()
        raise


def urdf_joint_of_motor(joint_names: Sequence[str], motor_names: Sequence[str]) -> dict[str, str]:
    """Motor → URDF joint: by name (SO-100/SO-101), else in order (Koch: ``joint1`` … in motor order)."""
    names = list(joint_names)
    motors = list(motor_names)
    if all(m in names for m in motors):
        return {m: m for m in motors}
    return dict(zip(motors, names, strict=False))


def open_lerobot_auto_page(
    robot: str,
    motor_names: Sequence[str],
    *,
    inner: Any = None,
    host: str = "127.0.0.1",
    port: int = 8080,
) -> Any:
    """Start the page for ``robocal lerobot calibrate --auto --view``: the stop search drawn on the arm.

    The servo drivers' joint frame counts ticks from 0 (``ticks·2π/4096``); the arm's URDF has its zero at the
    middle pose, half a turn, which is subtracted before drawing (as ``lerobot calibrate --view`` does).

    Returns:
        The :class:`~robocal.viewer.autocal_page.AutoSweepWebView` to pass as the run's view.

    Raises:
        CalibError: The URDF does not load, a port in use, viser missing — before anything moves.
    """
    from .autocal_page import open_auto_sweep_page
    from .model import load_robot_model

    urdf = lerobot_shapes_urdf(robot)
    joint_of = urdf_joint_of_motor(load_robot_model(urdf).actuated, motor_names)
    return open_auto_sweep_page(
        urdf,
        inner=inner,
        joint_of=joint_of,
        q_offset_rad=math.pi,
        host=host,
        port=port,
        title=f"lerobot calibrate --auto: {robot}",
    )
