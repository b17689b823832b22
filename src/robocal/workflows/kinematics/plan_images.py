"""Pose planning for camera (tag) sessions: ``robocal kinematics plan --kind tag``.

The set-up is given nominally: where the camera is (fixed in the base frame, or on the tip link with
``camera_on_tool``), where the target is (on the tip link, or fixed in the base frame), the camera's intrinsics
(a camera_info YAML, e.g. from ``kinematics camera-calibrate``) and the target. Candidates are configurations
inside the joint limits where the camera sees the whole target (:func:`robocal.core.pose_plan.target_visible`);
:func:`robocal.core.pose_plan.plan_image_poses` picks the images greedily and I-optimal for the reprojection
model ``identify --kind tag`` fits (kinematics, camera pose or target place, mounting, optionally the
intrinsics), Bayesian with ``prior`` (the URDF's tolerance on the kinematic parameters, as ``identify --kind tag
--prior`` uses it). The plan is the same joint CSV as for points (``pose`` + one column per joint, radians), for
``kinematics record --kind tag --plan``.
"""

from __future__ import annotations

import math
import os
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ...backends.vision import parse_target
from ...core.arrays import FloatArray
from ...core.identifiability import Identifiability
from ...core.kinematic_errors import ErrorModel
from ...core.pose_plan import plan_image_poses, target_visible
from ...core.se3 import homogeneous, matrix_from_rpy_urdf
from ...errors import UsageError
from ...fileio import atomic_write_text, check_output_path
from ...formats.camera_info import read_camera_info
from ...formats.kinematic_data import read_joint_table, session_csv
from ...formats.urdf import UrdfDocument
from ...formats.urdf_chain import chain_from_urdf
from .fit import PriorSigmas, check_seed
from .job import as_prior
from .plan import sampling_bounds

__all__ = ["ImagePlanRequest", "ImagePlanResult", "frame_from_pose", "plan_images"]

_BATCH = 20_000
_MAX_DRAWS = 1_000_000


@dataclass(frozen=True, eq=False)
class ImagePlanResult:
    """Images planned for a tag session.

    Attributes:
        q_rad: ``(N, n_q)`` joint targets, rad (m for prismatic joints).
        joint_names: Column order.
        identifiability: What the images at these poses identify (rank of the reprojection problem).
        out: CSV written.
        candidates: Candidate configurations where the camera sees the whole target.
        drawn: Random configurations drawn to find them (or the poses of the candidates file).
        prediction_sigma_m: Predicted one-σ error of the target's centre in the camera frame (camera on the
            tool: the camera's centre in the target frame) after identification, RMS over the candidates, m.
    """

    q_rad: FloatArray
    joint_names: tuple[str, ...]
    identifiability: Identifiability
    out: Path
    candidates: int
    drawn: int
    prediction_sigma_m: float


def frame_from_pose(values: Sequence[float], flag: str, look_at: Sequence[float] | None = None) -> FloatArray:
    """``(4, 4)`` from ``x, y, z, roll, pitch, yaw`` (m, rad, URDF rpy), or ``x, y, z`` looking at ``look_at``.

    With ``look_at`` the frame is a camera's (OpenCV: z towards ``look_at``, x right, y down, the base's z up).
    """
    v = [float(x) for x in values]
    if not all(math.isfinite(x) for x in v):
        raise UsageError(f"{flag}: values must be finite numbers, got {v}")
    if look_at is not None:
        if len(v) != 3:
            raise UsageError(f"{flag} with --look-at: expected x,y,z (metres), got {len(v)} numbers")
        from .vision_sim import look_at as look

        if np.linalg.norm(np.subtract(look_at, v)) < 1e-6:
            raise UsageError(f"{flag}: the camera cannot look at its own position")
        return look(v, look_at)
    if len(v) != 6:
        raise UsageError(f"{flag}: expected x,y,z,roll,pitch,yaw (metres, radians), got {len(v)} numbers")
    return np.asarray(homogeneous(matrix_from_rpy_urdf(np.array(v[3:])), v[:3]), dtype=np.float64)


@dataclass(frozen=True, eq=False)
class ImagePlanRequest:
    """Choose ``poses`` configurations where the camera sees the target that identify the set-up best.

    The options are checked when the request is built; files when :func:`plan_images` runs.

    Attributes:
        urdf: Expanded URDF.
        out: CSV to write (atomically; nothing is written on an error).
        camera: Camera intrinsics (ROS camera_info YAML): camera matrix and image size.
        target: ``apriltag:…`` or ``charuco:…``.
        T_camera: Camera fixed: ``T_base_camera`` (OpenCV axes); camera on the tool: ``T_tip_camera``.
        T_target: Camera fixed: ``T_tip_target``; camera on the tool: ``T_base_target``.
        camera_on_tool: The set-up.
        refine_intrinsics: Plan for ``identify --refine-intrinsics``.
        poses: How many images.
        base_link: First link of the chain (default: the URDF root).
        tip_link: Link the target (camera) is on.
        noise_px: Corner noise per axis, pixels (the predicted σ).
        candidates: How many candidates where the camera sees the target to draw (uniform inside the limits,
            ``margin_rad`` inside them; up to a million configurations are tried).
        candidates_file: Take the candidates from this joint table instead (each checked against the limits;
            those where the camera does not see the target are left out).
        margin_rad: Distance kept from the joint limits by the random candidates.
        seed: Seed of the random candidates.
        prior: Plan for ``identify --kind tag --prior`` (True: the default tolerance): Bayesian I-optimal, the
            prior on the kinematic parameters only (not on the camera pose, the mounting or the intrinsics),
            weighed against ``noise_px``.

    Raises:
        UsageError: A pose or candidate count below 1, a noise that is not a positive number, a negative seed.
    """

    urdf: str | os.PathLike[str]
    out: str | os.PathLike[str]
    camera: str | os.PathLike[str]
    target: str
    T_camera: FloatArray
    T_target: FloatArray
    camera_on_tool: bool = False
    refine_intrinsics: bool = False
    poses: int = 40
    base_link: str | None = None
    tip_link: str | None = None
    noise_px: float = 0.3
    candidates: int = 2000
    candidates_file: str | os.PathLike[str] | None = None
    margin_rad: float = 0.05
    seed: int = 0
    prior: bool | PriorSigmas = False

    def __post_init__(self) -> None:
        if self.poses < 1:
            raise UsageError(f"--poses must be at least 1, got {self.poses}")
        if self.candidates < 1:
            raise UsageError(f"--candidates must be at least 1, got {self.candidates}")
        if not (math.isfinite(self.noise_px) and self.noise_px > 0.0):
            raise UsageError(f"--noise-px must be a positive number, got {self.noise_px}")
        check_seed(self.seed)


def plan_images(request: ImagePlanRequest) -> ImagePlanResult:
    """Plan the images of ``request`` greedily (I-optimal for the reprojection model) and write them as a CSV.

    Args:
        request: What to plan (checked when it was built).

    Returns:
        The :class:`ImagePlanResult`.

    Raises:
        CalibError: A bad camera file or target, no or too few poses where the camera sees the target, too few
            images for the identifiable unknowns.
    """
    r = request
    camera_on_tool, T_camera, T_target, candidates, candidates_file = (
        r.camera_on_tool, r.T_camera, r.T_target, r.candidates, r.candidates_file,
    )  # fmt: skip
    prior_s = as_prior(r.prior)
    out_path = check_output_path(
        r.out, "--out", inputs={"--urdf": r.urdf, "--camera": r.camera, "--candidates-file": candidates_file}
    )
    tgt = parse_target(r.target)
    cam = read_camera_info(r.camera)
    chain = chain_from_urdf(UrdfDocument.load(r.urdf).model(), r.base_link, r.tip_link)
    if camera_on_tool:
        model = ErrorModel(
            chain, T_world_base=np.asarray(np.linalg.inv(T_target), np.float64), T_tip_tool=T_camera
        )
    else:
        model = ErrorModel(
            chain, T_world_base=np.asarray(np.linalg.inv(T_camera), np.float64), T_tip_tool=T_target
        )
    corners = tgt.object_points()
    size = (cam.width, cam.height)

    def seen(q: FloatArray) -> FloatArray:
        T = model.tool_poses(q)
        T_cam_target = np.linalg.inv(T) if camera_on_tool else T
        return q[target_visible(T_cam_target, corners, tgt.front_normal(), cam.K, size)]

    where = "on the tool" if camera_on_tool else "fixed"
    if candidates_file is not None:
        q_all = chain.check_q(
            read_joint_table(candidates_file, chain.joint_names), what=f"{candidates_file}: pose"
        )
        drawn = int(q_all.shape[0])
        cand = seen(q_all)
    else:
        lo, up = sampling_bounds(chain, r.margin_rad)
        rng = np.random.default_rng(r.seed)
        found: list[FloatArray] = []
        drawn = n_found = 0
        while n_found < candidates and drawn < _MAX_DRAWS:
            batch = seen(rng.uniform(lo, up, (_BATCH, chain.n_q)))
            drawn += _BATCH
            found.append(batch)
            n_found += batch.shape[0]
        cand = np.concatenate(found)[:candidates]
    if cand.shape[0] == 0:
        raise UsageError(
            f"the camera ({where}) sees the whole target {tgt.text} in none of {drawn} poses inside the joint "
            "limits: check --camera-pose and --target-pose (metres, radians; the camera looks along its z) and "
            "the image size in the camera file"
        )
    plan = plan_image_poses(
        model, cand, corners, cam.K, r.poses, camera_on_tool=camera_on_tool, refine_intrinsics=r.refine_intrinsics,
        noise_px=r.noise_px, prior_sigma=None if prior_s is None else prior_s.model_sigmas(model, tool_free=True),
    )  # fmt: skip
    q = cand[plan.index]
    written = atomic_write_text(out_path, session_csv(q, chain.joint_names, {}))
    return ImagePlanResult(
        q,
        chain.joint_names,
        plan.identifiability,
        written,
        int(cand.shape[0]),
        drawn,
        plan.prediction_sigma_m,
    )
