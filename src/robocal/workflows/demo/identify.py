"""``robocal demo --robot so101|koch --identify``: simulated kinematic identification, end to end.

The ``identify`` job of :data:`robocal.workflows.demo.job.JOBS`: simulate 50 poses chosen for observability and 17
random held-out poses (a separate validation session) of an arm with hidden errors (1 mm origins, 0.5° tilts,
2° zeros), identify it from the 50, and check the identified model against the hidden truth on the held-out poses
and on 500 new ones; for the SO-101 also the image part (rendered AprilTag images, camera
calibration, joint hand-eye). The results go to the CLI in an :class:`IdentifyDemo` for its printers.
"""

from __future__ import annotations

import os
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

from ...core.arrays import FloatArray
from ...errors import BackendNotAvailableError

if TYPE_CHECKING:
    from ..kinematics.job import IdentifyResult
    from ..kinematics.sim import SimulationResult
    from ..kinematics.vision import ImageIdentifyResult

__all__ = [
    "DEMO_HELD_OUT",
    "DEMO_POSES",
    "IDENTIFY_INTRO",
    "IMAGES_INTRO",
    "IdentifyDemo",
    "ImagesDemo",
    "identify_demo",
    "simulate_and_identify",
]

DEMO_POSES = 50
"""Poses the demo plans and fits."""
DEMO_HELD_OUT = 17
"""Random poses of the demo's separate held-out session."""

IDENTIFY_INTRO = (
    "[bold]kinematics demo[/]: simulated {robot} with hidden errors (1 mm origins, 0.5° tilts, 2° zeros), "
    "4096-tick joints, 0.5 mm marker noise, 50 poses chosen for observability"
)
"""The demo's first line (rich markup; ``{robot}``)."""

IMAGES_INTRO = (
    "[bold]images[/]: a fixed simulated camera (1280×960) sees a 60 mm AprilTag on the gripper in 40 poses; "
    "20 ChArUco images calibrate it first"
)
"""The first line of the image part (rich markup)."""


@dataclass(frozen=True)
class ImagesDemo:
    """The image part of the demo (SO-101).

    Attributes:
        skipped: Why the part did not run (OpenCV missing), or None.
        camera_line: The camera calibration against its truth (empty when skipped).
        result: The joint hand-eye identification, or None when skipped.
        truth_line: The identified target centre against the hidden truth (empty when skipped).
    """

    skipped: str | None
    camera_line: str = ""
    result: ImageIdentifyResult | None = None
    truth_line: str = ""


@dataclass(frozen=True)
class IdentifyDemo:
    """What ``demo --identify`` found, in the order it is printed.

    Attributes:
        identification: The marker-point identification.
        truth_line: The identified errors against the hidden truth on the held-out poses, and nominal and
            identified ones on 500 new poses.
        images: The image part, or None (the robot has none).
    """

    identification: IdentifyResult
    truth_line: str
    images: ImagesDemo | None = None

    @property
    def has_warnings(self) -> bool:
        """A warning from either identification, or the image part skipped."""
        img = self.images
        return bool(self.identification.warnings) or (
            img is not None
            and (img.skipped is not None or (img.result is not None and bool(img.result.warnings)))
        )


def simulate_and_identify(
    robot: str, folder: str | os.PathLike[str], *, seed: int = 0, **options: Any
) -> tuple[SimulationResult, IdentifyResult, FloatArray]:
    """The demo's session: 50 planned poses fitted, 17 random poses of a separate session held out.

    Args:
        robot: ``so101`` or ``koch``.
        folder: Folder for the simulated files.
        seed: Seed of the hidden errors, the poses and the noise (0.5 mm per axis, 4096-tick joints).
        **options: More fields of :class:`robocal.workflows.kinematics.request.IdentifyRequest` (``dh``,
            ``outputs``, …).

    Returns:
        The simulation, the identification and the identified model's errors (m) against the hidden truth at
        the held-out poses, ``(17,)``.
    """
    import numpy as np

    from ..kinematics import job as wf
    from ..kinematics import sim as sim_wf

    sim = sim_wf.simulate(
        sim_wf.SimulationRequest(
            robot, folder, poses=DEMO_POSES, noise_m=0.5e-3, seed=seed, validation_poses=DEMO_HELD_OUT
        )
    )
    assert sim.validation is not None and sim.validation_truth_m is not None
    result = wf.identify(wf.IdentifyRequest(
        sim.urdf, sim.data, tip_link=sim.tip_link, tool_xyz_m=sim.tool_xyz_m, validate_data=sim.validation,
        **options,
    ))  # fmt: skip
    predicted = result.fit.problem.model.points(result.validation.q_rad, result.fit.x)
    held = np.asarray(np.linalg.norm(predicted - sim.validation_truth_m, axis=1), dtype=np.float64)
    return sim, result, held


class _Steps:
    """Progress lines ``step i/n: what (t s)`` through ``say`` as each step of the demo starts."""

    def __init__(self, say: Callable[[str], object], total: int) -> None:
        self._say = say
        self._total = total
        self._done = 0
        self._t0 = time.monotonic()

    def start(self, what: str) -> None:
        self._done += 1
        elapsed_s = time.monotonic() - self._t0
        self._say(f"step {self._done}/{self._total}: {what} ({elapsed_s:.0f} s)")

    def detail(self, what: str) -> None:
        """A line inside the current step: ``  what (t s)``."""
        self._say(f"  {what} ({time.monotonic() - self._t0:.0f} s)")


def identify_demo(robot: str, folder: Path, say: Callable[[str], object] = lambda _line: None) -> IdentifyDemo:
    """Simulate, identify and check ``robot`` (``so101``: then the image part in ``folder/tag``).

    Args:
        robot: ``so101`` or ``koch``.
        folder: Folder for the files (it exists).
        say: Called with a progress line as each step starts (the whole demo takes a minute or two).

    Returns:
        The :class:`IdentifyDemo`.
    """
    import numpy as np

    steps = _Steps(say, 5 if robot == "so101" else 2)
    steps.start(
        f"simulating {DEMO_POSES} planned poses and {DEMO_HELD_OUT} held-out ones, then identifying "
        "(analysis, fit, DH-like fit)"
    )
    from ..kinematics.request import IdentifyOutputs

    sim, result, held = simulate_and_identify(
        robot, folder, dh=True,
        outputs=IdentifyOutputs(out=folder / f"{robot}_identified.urdf", report=folder / "report.json"),
    )  # fmt: skip
    steps.start("checking the identified model against the hidden truth on 500 new poses")
    rng = np.random.default_rng(1)
    q = sim.arm.sample_q(500, rng)
    model = result.fit.problem.model
    truth = sim.arm.true_points(q)
    err = np.linalg.norm(model.points(sim.arm.read(q), result.fit.x) - truth, axis=1)
    nominal = np.linalg.norm(model.points(sim.arm.read(q)) - truth, axis=1)
    line = (
        f"against the hidden truth: the {held.size} held-out poses mean {held.mean() * 1e3:.3f} mm, max "
        f"{held.max() * 1e3:.3f} mm; 500 new poses: nominal mean {nominal.mean() * 1e3:.2f} mm → identified "
        f"mean {err.mean() * 1e3:.3f} mm, max {err.max() * 1e3:.3f} mm"
    )
    images = _images_demo(robot, folder / "tag", steps) if robot == "so101" else None
    return IdentifyDemo(result, line, images)


def _images_demo(robot: str, folder: Path, steps: _Steps) -> ImagesDemo:
    """The image part: rendered AprilTag images, camera calibration, joint hand-eye."""
    import numpy as np

    from ..kinematics import vision as vis_wf
    from ..kinematics.request import IdentifyOutputs

    folder.mkdir(exist_ok=True)
    steps.start("images: rendering 20 ChArUco and 40 AprilTag images")
    try:
        sim = vis_wf.simulate_images(vis_wf.SimImagesRequest(robot, folder, poses=40, seed=0))
    except BackendNotAvailableError as exc:  # pragma: no cover - OpenCV missing
        return ImagesDemo(f"skipping the image demo: {exc}")
    steps.start("images: calibrating the camera from the ChArUco images")
    cal = vis_wf.camera_calibrate(sim.calibration_images, sim.board, folder / "camera.yaml")
    steps.start("images: identifying the arm, the camera pose and the tag mounting from the tag images")
    camera_line = (
        f"camera-calibrate: fx {cal.camera.K[0, 0]:.1f} (true 905.0), RMS {cal.camera.rms_px:.3f} px"
    )
    result = vis_wf.identify_images(vis_wf.ImageIdentifyRequest(
        sim.urdf, sim.data, camera=folder / "camera.yaml", target=sim.target, tip_link=sim.tip_link,
        outputs=IdentifyOutputs(out=folder / f"{robot}_identified.urdf", report=folder / "report.json"),
    ), progress=steps.detail)  # fmt: skip
    q = sim.arm.sample_q(500, np.random.default_rng(1))
    truth = sim.arm.true_points(q)
    err = np.linalg.norm(result.model.points(sim.arm.read(q), result.fit.x) - truth, axis=1)
    start = np.linalg.norm(result.model.points(sim.arm.read(q)) - truth, axis=1)
    truth_line = (
        f"target centre against the hidden truth on 500 new poses (camera frame): start mean {start.mean() * 1e3:.2f} "
        f"mm → identified mean {err.mean() * 1e3:.3f} mm, max {err.max() * 1e3:.3f} mm"
    )
    return ImagesDemo(None, camera_line, result, truth_line)
