"""``robocal view``: the URDF robot in a local web page (viser), posed by live or recorded joint positions.

Install with ``pip install 'robocal[view]'`` (viser, yourdfpy, trimesh). Everything the page loads comes from
the installed viser package (its built web client); nothing is fetched from the internet.

Pieces (viser is imported only when a page starts):

* :func:`~robocal.viewer.model.load_robot_model` — URDF → :class:`~robocal.viewer.model.RobotModel`: actuated
  joints (the joint axis of every array, URDF order), limits, forward kinematics
  (:meth:`RobotModel.poses`), link shapes with meshes resolved (``package://`` via ``--package-path``) and
  simple shapes for missing meshes (one warning in :attr:`RobotModel.warnings`).
* :class:`~robocal.viewer.mapping.JointMapper` — raw source values → joint positions through a
  :class:`~robocal.core.jointmap.RobotCalibration` (joints it lacks pass through).
* :class:`~robocal.viewer.latest.LatestFrame` — the newest-frame mailbox: a 1 kHz source never queues
  behind a 30 Hz page; replaced frames are counted as dropped.
* :class:`~robocal.viewer.app.ViewerApp` — the page: robot, translucent ghost (``compare``), joint panel,
  messages, replay slider, page loop.
* :mod:`~robocal.viewer.feeds` — threads pushing frames from a source (:class:`SourceFeed`), a recording
  with play/pause/seek (:class:`ReplayFeed`), a function of time (:class:`CallableFeed`) or a polled device
  (:class:`PollFeed`).
* :func:`~robocal.viewer.session.open_view` — the whole ``robocal view`` command as a function.

Extending the page (sweep arcs, UR error arrows)::

    from robocal.viewer import ViewerApp, load_robot_model, JointMapper

    model = load_robot_model("robot.urdf")
    app = ViewerApp(model, calibration=JointMapper(model.actuated, cal, "cal.yaml"), port=0).start()
    print(app.url)

    def draw(app: ViewerApp, update: PageUpdate) -> None:   # runs on the page thread after each pose
        T = update.poses[model.child_link("left_elbow_pitch")]  # 4x4 world pose of a link
        app.server.scene.add_icosphere("/overlay/elbow", radius=0.03, position=tuple(T[:3, 3]))

    app.add_hook(draw)
    app.push(t_s, raw)        # any thread, any rate: the newest frame wins
    app.message("sweeping…")  # a line on the page (info / warning / error)
    app.stop()

``app.server`` is the :class:`viser.ViserServer` (add scene nodes under your own root, e.g. ``/sweep``);
``app.robot.paths[link]`` is the scene path of a link's frame, so an overlay added as a child of it moves with
the link. Tests call ``app.start(loop=False)`` and drive :meth:`ViewerApp.step` themselves.

Page state (for tests and browsers):

* :meth:`ViewerApp.status` returns a dict: ``updates`` (page updates made), ``frames_in``,
  ``frames_dropped``, ``latency_s``, ``source`` (``waiting|running|finished|failed``), ``calibration``,
  ``compare``, ``t_s``, ``messages`` (``[{level, text}]``), ``replay`` (``playing``, ``position_s``,
  ``start_s``, ``end_s``) and ``joints``: ``[{name, raw, q, q_compare, lower, upper, outside, color}]``
  (``color`` is ``"red"`` outside the limits, else ``"normal"``; NaN and infinite limits are ``null``).
* In the page: ``#robocal-status`` carries the same JSON in its ``data-status`` attribute and the update
  count in ``data-updates`` (the page loop sends it at most 10 times a second, when a joint crosses a limit,
  and once due after the updates stop; :meth:`ViewerApp.step` sends it with every update);
  ``#robocal-frame[data-updates]`` counts every page update; the joint table ``#robocal-joints`` has one ``tr.robocal-joint`` per joint with
  ``data-joint``, ``data-q`` and ``data-outside`` (``1`` when red); ``#robocal-messages`` holds the messages
  (``.robocal-error`` for errors) and ``data-source``.
"""

from __future__ import annotations

from .app import PageUpdate, ViewerApp
from .latest import Frame, LatestFrame
from .mapping import JointMapper
from .model import JointInfo, LinkShape, RobotModel, load_robot_model, parse_package_paths, resolve_mesh

__all__ = [
    "Frame",
    "JointInfo",
    "JointMapper",
    "LatestFrame",
    "LinkShape",
    "PageUpdate",
    "RobotModel",
    "ViewerApp",
    "load_robot_model",
    "parse_package_paths",
    "resolve_mesh",
]
