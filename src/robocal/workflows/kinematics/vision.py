"""Kinematic identification from camera images: camera calibration, tag sessions, and their simulation.

Set-ups: a camera fixed in the world and the target (AprilTag or ChArUco, :mod:`robocal.backends.vision`) on the
tool, or a camera on the tool and the target fixed in the world (``camera_on_tool``). ``camera_calibrate`` estimates the intrinsics from ChArUco images (``cv2.calibrateCamera``);
``identify_images`` detects the target in each image of a session, starts the camera pose and the target's
mounting from a closed-form hand-eye solution, then estimates both jointly with the kinematic parameters from the
reprojection errors (:class:`robocal.core.kinematic_images.ImageProblem`). ``simulate_images`` renders such a session from a simulated arm with hidden
errors, plus calibration images of a ChArUco board, for the tests and ``demo --identify``.
"""

from __future__ import annotations

import math
import os
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ...backends.vision import (
    CameraIntrinsics,
    Detection,
    Target,
    calibrate_camera,
    detect,
    normalised,
    parse_target,
    read_image,
    solve_pnp,
)
from ...core.arrays import FloatArray
from ...core.chain import SerialChain
from ...core.kinematic_errors import ErrorModel
from ...core.kinematic_images import INTRINSICS, ImageObservations, ImageProblem, hand_eye
from ...errors import UsageError
from ...fileio import check_output_path
from ...formats.camera_info import read_camera_info, write_camera_info
from ...formats.kinematic_data import read_image_session
from ...formats.urdf import UrdfDocument
from ...formats.urdf_chain import chain_from_urdf
from . import image_gates as ig
from . import report as kr
from .export import check_export_paths, check_ur_chain
from .fit import FitResult, fit, structural_image_analysis
from .gates import check_rank, distinct_poses
from .request import ImageIdentifyRequest

__all__ = [
    "SIM_CAMERA_K",
    "CameraCalibrationResult",
    "ImageIdentifyRequest",
    "ImageIdentifyResult",
    "SimImagesRequest",
    "SimImagesResult",
    "camera_calibrate",
    "detect_session",
    "identify_images",
    "look_at",
    "simulate_images",
]



@dataclass(frozen=True, eq=False)
class CameraCalibrationResult:
    """Intrinsics from ``camera_calibrate``.

    Attributes:
        camera: The intrinsics (with the RMS reprojection error).
        out: The camera_info YAML written.
        used: Images the board was found in.
        warnings: Skipped images.
    """

    camera: CameraIntrinsics
    out: Path
    used: int
    warnings: tuple[str, ...]


def camera_calibrate(
    images: Sequence[str | os.PathLike[str]], board: str, out: str | os.PathLike[str]
) -> CameraCalibrationResult:
    """Calibrate a camera from ChArUco board images and write its ROS camera_info YAML.

    Raises:
        UsageError: Not a ChArUco board, fewer than 4 images with the board, images of different sizes.
        FileFormatError: An unreadable image.
    """
    out_path = check_output_path(out, "--out", inputs={f"image {i + 1}": p for i, p in enumerate(images)})
    target = parse_target(board, "--board")
    if target.kind != "charuco":
        raise UsageError(
            "--board must be a ChArUco board (charuco:<cols>x<rows>:<square_mm>:<marker_mm>[:<dict>])"
        )
    if not images:
        raise UsageError("no images given")
    loaded = [(str(p), read_image(p)) for p in images]
    camera, warnings = calibrate_camera(loaded, target)
    written = write_camera_info(out_path, camera)
    return CameraCalibrationResult(camera, written, len(loaded) - len(warnings), tuple(warnings))


PROGRESS_EVERY = 10
"""``detect_session`` reports its progress after every this many images (and after the last)."""


def detect_session(
    q_rad: FloatArray,
    images: Sequence[str],
    target: Target,
    camera: CameraIntrinsics,
    progress: Callable[[str], object] | None = None,
) -> tuple[ImageObservations, NDArray[np.int64], list[str]]:
    """Detect the target in every image of a session.

    Args:
        q_rad: ``(N, n_q)`` joint readings, one row per image.
        images: The image files, in session order.
        target: What to look for.
        camera: The intrinsics (the images must have its size).
        progress: Called with ``detecting the target: i of N images`` every :data:`PROGRESS_EVERY` images.

    Returns:
        The observations of the images the target was found in, the session rows they come from, and one
        warning per image without the target (that pose is skipped).

    Raises:
        FileFormatError: An image that cannot be read, or whose size differs from the camera's.
    """
    from ...errors import FileFormatError

    def found(path: str) -> Detection | None:
        img = read_image(path)
        if img.shape[:2] != (camera.height, camera.width):
            raise FileFormatError(
                f"image {path} is {img.shape[1]}x{img.shape[0]}; the camera was calibrated at "
                f"{camera.width}x{camera.height}"
            )
        return detect(img, target)

    obj = target.object_points()
    rows: list[int] = []
    poses: list[NDArray[np.int64]] = []
    corners: list[FloatArray] = []
    uvs: list[FloatArray] = []
    Ts: list[FloatArray] = []
    warnings: list[str] = []
    def _add_detection(i: int, path: str, det: Detection | None) -> None:
        if det is None:
            warnings.append(f"pose {i + 1} ({path}): target {target.text} not found; pose skipped")
            return
        k = len(rows)
        rows.append(i)
        poses.append(np.full(det.corner_ids.size, k))
        corners.append(obj[det.corner_ids])
        uvs.append(normalised(det.pixels, camera))
        Ts.append(solve_pnp(obj[det.corner_ids], det.pixels, camera))

    for i, path in enumerate(images):
        _add_detection(i, path, found(path))
        if progress is not None and ((i + 1) % PROGRESS_EVERY == 0 or i + 1 == len(images)):
            progress(f"detecting the target: {i + 1} of {len(images)} images")
    r = np.asarray(rows, dtype=np.int64)
    if r.size == 0:
        return (
            ImageObservations(
                q_rad[:0], np.zeros(0, np.int64), np.zeros((0, 3)), np.zeros((0, 2)), camera.focal_px
            ),
            r,
            warnings,
        )
    return (
        ImageObservations(
            q_rad[r],
            np.concatenate(poses),
            np.concatenate(corners),
            np.concatenate(uvs),
            camera.focal_px,
            np.asarray(Ts),
            camera.K,
        ),
        r,
        warnings,
    )


@dataclass(frozen=True, eq=False)
class ImageIdentifyResult:
    """What ``identify_images`` found and wrote.

    Attributes:
        fit: The fit (its pose errors are RMS reprojection errors per image, pixels).
        validation: Held-out observations.
        validation_px: RMS reprojection error per held-out image with the identified model, pixels.
        start_validation_px: The same with the nominal kinematics and the hand-eye start values.
        chain: Corrected chain (offsets folded into the origins).
        T_cam_base: Identified camera → base pose (camera on the tool: the target → base pose).
        T_tip_target: Identified target pose on the tip link (camera on the tool: the camera's pose on it).
        model: The error model (camera frame as its world).
        urdf_out: Corrected URDF written, or None.
        report_out: JSON report written, or None.
        report: The report.
        warnings: Per-pose and other warnings.
    """

    fit: FitResult
    validation: ImageObservations
    validation_px: FloatArray
    start_validation_px: FloatArray
    chain: SerialChain
    T_cam_base: FloatArray
    T_tip_target: FloatArray
    model: ErrorModel
    urdf_out: Path | None
    report_out: Path | None
    report: dict[str, Any]
    warnings: tuple[str, ...] = field(default_factory=tuple)


def _intrinsics_report(problem: ImageProblem, result: FitResult, K: FloatArray) -> dict[str, Any]:
    """The camera matrix used (calibrated, or refined with the σ of each refined value)."""
    if not problem.refine_intrinsics:
        return {"refined": False, "K": np.asarray(K).tolist()}
    n = len(problem.free)
    sig = result.sigma[n:]
    return {
        "refined": True,
        "K_calibrated": np.asarray(K).tolist(),
        "K": problem.camera_matrix(result.theta).tolist(),
        "sigma_px": {k.split(".")[1]: float(v) if math.isfinite(v) else None for k, v in zip(INTRINSICS, sig, strict=True)},
    }


def _image_names(rows: NDArray[np.int64], images: Sequence[str]) -> list[str]:
    """``image N (file)`` per session row (N 1-based, as the CSV's rows)."""
    return [f"image {int(i) + 1} ({images[int(i)]})" for i in rows]


def identify_images(
    request: ImageIdentifyRequest, *, progress: Callable[[str], object] | None = None
) -> ImageIdentifyResult:
    """Identify a chain, the camera's pose and the target's mounting from images of a target (``--kind tag``).

    Args:
        request: What to identify and what to write (checked when it was built).
        progress: Called with a line as each stage starts (detection every :data:`PROGRESS_EVERY` images, the
            fit, the writing): a session of 40 images takes half a minute of CPU, most of it detecting.

    Returns:
        The :class:`ImageIdentifyResult`; files are written only after everything succeeded.

    Raises:
        CalibError: Unreadable files or images, poses outside the limits, too few images with the target.
    """
    r, o = request, request.outputs
    urdf, data, camera, camera_on_tool = r.urdf, r.data, r.camera, r.camera_on_tool
    refine_intrinsics = r.refine_intrinsics
    inputs = {"--urdf": urdf, "--data": data, "--camera": camera}
    paths = check_export_paths(o.out, o.report, o.joint_map_out, o.ur_yaml, o.joint_map, o.ur_hash, inputs)
    tgt = parse_target(r.target)
    cam = read_camera_info(camera)
    doc = UrdfDocument.load(urdf)
    chain = chain_from_urdf(doc.model(), r.base_link, r.tip_link)
    if o.ur_yaml is not None:
        check_ur_chain(chain)  # before any image is read: an option that cannot work is the first thing to say
    q, images = read_image_session(data, chain.joint_names)
    chain.check_q(q, what=f"{data}: pose")
    obs, rows, warnings = detect_session(q, images, tgt, cam, progress)
    if obs.n_poses < 3:
        raise UsageError(
            f"the target was found in {obs.n_poses} of {len(images)} images; at least 3 are needed (20 or more "
            "for a useful result)"
        )
    first, _ = distinct_poses(obs.q_rad, chain, r.ticks_per_turn)
    if first.size < 3:  # the hand-eye start needs three different poses
        raise UsageError(
            f"the target was found in {obs.n_poses} images at {first.size} distinct "
            f"{'pose' if first.size == 1 else 'poses'} (the same encoder readings); at least 3 different poses "
            "are needed (20 or more for a useful result)"
        )
    nominal = ErrorModel(chain)
    assert obs.T_cam_target is not None
    seen = np.linalg.inv(obs.T_cam_target) if camera_on_tool else obs.T_cam_target
    X, Y = hand_eye(seen, nominal.tool_poses(obs.q_rad))
    model = ErrorModel(chain, T_world_base=X, T_tip_tool=Y)
    free, x0 = tuple(range(model.n_params)), np.zeros(model.n_params)
    structural = structural_image_analysis(ImageProblem(
        model, obs, free, x0, camera_on_tool=camera_on_tool, refine_intrinsics=refine_intrinsics
    ))  # fmt: skip
    split = ig.split_images(
        obs.q_rad, chain, structural.rank, fraction=r.validate_fraction, seed=r.seed,
        ticks_per_turn=r.ticks_per_turn, source=str(data),
    )  # fmt: skip
    warnings += split.warnings
    train_rows, val_rows = split.train_rows, split.validation_rows
    train, val = obs.subset(train_rows), obs.subset(val_rows)
    problem = ImageProblem(
        model, train, tuple(range(model.n_params)), np.zeros(model.n_params), camera_on_tool=camera_on_tool,
        refine_intrinsics=refine_intrinsics,
    )  # fmt: skip
    if progress is not None:
        progress(
            f"fitting {train.n_poses} images: the kinematics, the {'camera mounting' if camera_on_tool else 'camera pose'} "
            f"and the {'target place' if camera_on_tool else 'target mounting'}"
        )
    result = fit(problem, huber_m=r.huber_px, prior=r.prior, structural=structural)
    check_rank(result.identifiability, structural)
    if not result.success:
        warnings.append("the optimiser stopped before converging; check the images and joint readings")
    val_problem = ImageProblem(
        model, val, problem.free, np.zeros(model.n_params), camera_on_tool=camera_on_tool,
        refine_intrinsics=refine_intrinsics,
    )  # fmt: skip
    val_px = val_problem.pose_errors(result.theta) if val.n_poses else np.zeros(0)
    start_px = val_problem.pose_errors(np.zeros(problem.n_theta)) if val.n_poses else np.zeros(0)
    residual, residual_report = ig.residual_warnings(
        result.train_errors_m, val_px, _image_names(rows[train_rows], images),
        _image_names(rows[val_rows], images),
    )  # fmt: skip
    warnings += residual
    corrected, T_cam_base, T_tip_target = model.corrected(result.x)
    warnings += kr.condition_warnings(result, "show the target from more different arm poses")
    units = [model.parameters[i].unit if i < model.n_params else "px" for i in range(len(problem.names))]
    rep: dict[str, Any] = {
        "tool": "robocal kinematics identify --kind tag",
        "urdf": str(urdf),
        "data": str(data),
        "camera": str(camera),
        "target": tgt.text,
        "setup": "camera on the tool, target fixed in the world"
        if camera_on_tool
        else "camera fixed in the world, target on the tool",
        "chain": kr.chain_summary(chain),
        "images": {
            "total": len(images),
            "with_target": obs.n_poses,
            "fit": train.n_poses,
            "validation": val.n_poses,
        },
        **kr.fit_summary(result, problem.n_theta, kr.prior_summary(r.prior, noise=False)),
        "reprojection_px": {
            "fit": {
                "start": kr.error_stats(result.nominal_train_errors_m),
                "identified": kr.error_stats(result.train_errors_m),
            },
            "validation": {"start": kr.error_stats(start_px), "identified": kr.error_stats(val_px)},
        },
        "parameters": kr.parameter_rows(result, problem.names, units),
        "intrinsics": _intrinsics_report(problem, result, cam.K),
        **kr.model_summary(result, model, corrected),
        **(
            {"T_target_base": T_cam_base.tolist(), "T_tip_camera": T_tip_target.tolist()}
            if camera_on_tool
            else {"T_cam_base": T_cam_base.tolist(), "T_tip_target": T_tip_target.tolist()}
        ),
        "plausibility": {**split.report, **residual_report},
        "warnings": warnings,
    }
    written_urdf, written_report = kr.write_identify_files(
        doc, chain, model, result, paths, rep, warnings, o
    )  # fmt: skip
    return ImageIdentifyResult(
        result, val, val_px, start_px, corrected, T_cam_base, T_tip_target, model, written_urdf, written_report,
        rep, tuple(warnings),
    )  # fmt: skip


# the simulated sessions live in kinematic_vision_sim; re-exported for existing callers
from .vision_sim import SIM_CAMERA_K, SimImagesRequest, SimImagesResult, look_at, simulate_images  # noqa: E402
