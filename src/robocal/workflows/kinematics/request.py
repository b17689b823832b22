"""What an identification is asked to do, as one frozen value: the request, and the outputs both identifiers write.

:class:`IdentifyRequest` (points, touch, gauge), :class:`ImageIdentifyRequest` (camera images), and the files
both write, :class:`IdentifyOutputs`.
Each is a frozen value whose numbers and choices are checked once, when it is built (``UsageError`` naming the
flag, in the order ``robocal kinematics identify`` has always said them); files are checked by the job before
anything is read or written. The CLI builds them from its options; Python callers build them directly and pass
one to :func:`robocal.workflows.kinematics.job.identify` or
:func:`robocal.workflows.kinematics.vision.identify_images`.
"""

from __future__ import annotations

import math
import os
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field

from ...core.jointmap import RobotCalibration
from ...core.kinematic_problem import check_kind
from ...errors import UsageError, check_choice
from . import gates as gates
from . import plausibility as plaus
from .fit import PriorSigmas, check_seed

__all__ = [
    "DEFAULT_VALIDATE_FRACTION",
    "POINT_FRAMES",
    "IdentifyOutputs",
    "IdentifyRequest",
    "ImageIdentifyRequest",
]

DEFAULT_VALIDATE_FRACTION = 0.25
"""Share of a session's poses held out for validation when no separate validation session is given."""

POINT_FRAMES: tuple[str, ...] = ("base", "tracker")
"""``base``: points are given in the chain's base link frame. ``tracker``: in an unknown frame (registered)."""

PathLike = str | os.PathLike[str]


@dataclass(frozen=True)
class IdentifyOutputs:
    """The files an identification writes (each None: not asked for); checked before anything is read.

    Attributes:
        out: Corrected URDF to write.
        report: JSON report to write.
        joint_map: The raw → URDF joint map the readings went through (``lerobot export-urdf``); needed for
            ``joint_map_out``.
        joint_map_out: Write ``joint_map`` with the identified zero offsets in it (robocal joint-map YAML, the
            ``export-urdf`` format); the corrected URDF then leaves the offsets out of its origins.
        joint_map_ids: Motor ids written with the joint map.
        ur_yaml: Write ur_description's kinematics YAML of the corrected chain (UR chains only).
        ur_hash: ``calib_<uint64>`` for ``ur_yaml`` (default ``calib_0``, with a warning).
    """

    out: PathLike | None = None
    report: PathLike | None = None
    joint_map: RobotCalibration | None = None
    joint_map_out: PathLike | None = None
    joint_map_ids: Mapping[str, int] | None = None
    ur_yaml: PathLike | None = None
    ur_hash: str | None = None


@dataclass(frozen=True)
class IdentifyRequest:
    """Identify a URDF chain's geometric errors from a points, touch or gauge session.

    Attributes:
        urdf: Expanded URDF.
        data: Measurement CSV (see :mod:`robocal.formats.kinematic_data`).
        kind: ``points``, ``touch`` or ``gauge``.
        base_link: First link of the chain (default: the URDF root).
        tip_link: Link the tool is attached to (default: the only leaf).
        tool_xyz_m: Nominal tool point (marker, ball, tip) in the tip link's frame, m.
        frame: ``base`` or ``tracker`` (points only): the frame the points are measured in.
        validate_fraction: Share of poses held out for validation (None: 0.25, or 0 with ``validate_data``).
        validate_data: A separate session of held-out poses (the same columns as ``data``; touch groups matched by
            label); every pose of ``data`` is then fitted.
        huber_m: Huber loss scale (m); None for plain least squares.
        prior: A Gaussian prior around nominal (True: the default tolerance, :class:`PriorSigmas`); every
            parameter with a prior is then estimated (maximum a posteriori).
        gauge_distance_m: Socket distance of the gauge (``gauge`` only).
        dh: Also fit a DH-like model and report its (biased) errors.
        seed: Seed of the validation split (with ``validate_data`` only 0: nothing is drawn).
        ticks_per_turn: Encoder resolution poses are told apart at (0: exact readings); see
            :mod:`robocal.workflows.kinematics.gates`.
        noise_m: The marker noise per axis the user states (m); None: the residual is compared with what the
            fit estimates (:mod:`robocal.workflows.kinematics.plausibility`).
        max_correction_mm: Largest length correction a URDF is plausibly off by (mm).
        max_correction_deg: Largest angle correction (degrees).
        outputs: The files to write.

    Raises:
        UsageError: An unknown kind or frame, an option of another kind, a Huber scale, seed, tick count, noise
            or correction bound out of range, both ``validate_fraction`` and ``validate_data``.
    """

    urdf: PathLike
    data: PathLike
    kind: str = "points"
    base_link: str | None = None
    tip_link: str | None = None
    tool_xyz_m: Sequence[float] = (0.0, 0.0, 0.0)
    frame: str = "base"
    validate_fraction: float | None = None
    validate_data: PathLike | None = None
    huber_m: float | None = None
    prior: bool | PriorSigmas = False
    gauge_distance_m: float | None = None
    dh: bool = False
    seed: int = 0
    ticks_per_turn: int = gates.DEFAULT_TICKS_PER_TURN
    noise_m: float | None = None
    max_correction_mm: float = plaus.MAX_CORRECTION_MM
    max_correction_deg: float = plaus.MAX_CORRECTION_DEG
    outputs: IdentifyOutputs = field(default_factory=IdentifyOutputs)

    def __post_init__(self) -> None:
        check_kind(self.kind)
        check_choice("--frame", self.frame, POINT_FRAMES)
        if self.frame == "tracker" and self.kind != "points":
            raise UsageError(
                "--frame tracker applies to --kind points; touch and gauge data have no outside frame"
            )
        if self.kind == "gauge" and self.gauge_distance_m is None:
            raise UsageError("--kind gauge needs the socket distance (--gauge-mm)")
        if self.kind != "gauge" and self.gauge_distance_m is not None:
            raise UsageError("--gauge-mm applies to --kind gauge (the distance between its sockets)")
        huber = self.huber_m
        if huber is not None and not (math.isfinite(huber) and huber > 0):
            raise UsageError(f"--huber must be a positive distance, got {huber}")
        if self.validate_data is not None and self.validate_fraction is not None:
            raise UsageError("give --validate-fraction or --validate-data, not both")
        if self.validate_data is not None and self.seed != 0:
            raise UsageError("--seed seeds the random held-out share; with --validate-data nothing is drawn")
        check_seed(self.seed)
        gates.check_ticks(self.ticks_per_turn)
        plaus.check_bounds(self.max_correction_mm, self.max_correction_deg)
        noise = self.noise_m
        if noise is not None and not (math.isfinite(noise) and 0 < noise <= 1.0):
            raise UsageError(f"--noise-mm must be a positive number of millimetres up to 1000, got {noise * 1e3:g}")


@dataclass(frozen=True)
class ImageIdentifyRequest:
    """Identify a chain, the camera's pose and the target's mounting from images of a target (``--kind tag``).

    Attributes:
        urdf: Expanded URDF.
        data: Session CSV: the chain's joints and an ``image`` column.
        camera: The camera's intrinsics (ROS camera_info YAML, e.g. from ``camera_calibrate``).
        target: ``apriltag:…`` or ``charuco:…`` (see :func:`robocal.backends.vision.parse_target`).
        base_link: First link of the chain.
        tip_link: Link carrying the target (or the camera, with ``camera_on_tool``).
        validate_fraction: Share of images held out.
        huber_px: Huber loss scale in pixels (None: plain least squares).
        seed: Seed of the validation split.
        camera_on_tool: The camera is on the tip link and the target fixed in the world (eye-in-hand); the
            camera's mounting and the target's place are estimated instead of the camera pose and the target
            mounting.
        refine_intrinsics: Estimate the camera's ``fx, fy, cx, cy`` jointly with the rest (the lens distortion
            stays as calibrated); the refined values and their σ are in the report.
        prior: A Gaussian prior around the nominal kinematics (not on the camera pose, the mounting or the
            intrinsics); the noise that weighs it is estimated from the reprojection errors, pixels.
        ticks_per_turn: Encoder resolution images are told apart at (0: exact readings): images at the same
            readings are one pose (:mod:`robocal.workflows.kinematics.image_gates`).
        outputs: The files to write.

    Raises:
        UsageError: ``validate_fraction`` outside [0, 1), a Huber scale that is not a positive number, a negative
            seed or tick count.
    """

    urdf: PathLike
    data: PathLike
    camera: PathLike
    target: str
    base_link: str | None = None
    tip_link: str | None = None
    validate_fraction: float = DEFAULT_VALIDATE_FRACTION
    huber_px: float | None = None
    seed: int = 0
    camera_on_tool: bool = False
    refine_intrinsics: bool = False
    prior: PriorSigmas | None = None
    ticks_per_turn: int = gates.DEFAULT_TICKS_PER_TURN
    outputs: IdentifyOutputs = field(default_factory=IdentifyOutputs)

    def __post_init__(self) -> None:
        if not 0.0 <= self.validate_fraction < 1.0:
            raise UsageError(f"--validate-fraction must be in [0, 1), got {self.validate_fraction}")
        huber = self.huber_px
        if huber is not None and not (math.isfinite(huber) and huber > 0):
            raise UsageError(f"--huber must be a positive number of pixels, got {huber}")
        check_seed(self.seed)
        gates.check_ticks(self.ticks_per_turn)

