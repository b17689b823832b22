"""Simulated camera sessions for kinematic identification from images.

A session rendered from a simulated arm with hidden errors, plus calibration images of a ChArUco board, for the
tests and ``demo --identify``.
The simulated camera is fixed in the world and looks at a target on the tool, or (``camera_on_tool``) sits on the
tool and looks at a target fixed in the world: the two set-ups :mod:`robocal.workflows.kinematics.vision`
identifies.
"""

from __future__ import annotations

import json
import math
import os
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from ...backends.sim.kinematic_arm import SimulatedKinematicArm, hidden_errors
from ...backends.vision import (
    Target,
    parse_target,
    render,
    write_image,
)
from ...core.arrays import FloatArray
from ...core.kinematic_errors import ErrorModel
from ...core.kinematic_problem import plan_poses
from ...core.pose_plan import plan_image_poses, target_visible
from ...core.se3 import homogeneous, matrix_from_rpy_urdf
from ...errors import UsageError
from ...fileio import atomic_write_bytes, atomic_write_text
from ...formats.kinematic_data import session_csv
from ...formats.urdf import UrdfDocument
from ...formats.urdf_chain import chain_from_urdf

__all__ = ["SIM_CAMERA_K", "SimImagesRequest", "SimImagesResult", "look_at", "simulate_images"]



def look_at(
    eye: Sequence[float], centre: Sequence[float], up: Sequence[float] = (0.0, 0.0, 1.0)
) -> FloatArray:
    """``T_base_cam`` ``(4, 4)`` of a camera at ``eye`` looking at ``centre`` (OpenCV: z forward, y down)."""
    e, c, u = (np.asarray(v, dtype=np.float64) for v in (eye, centre, up))
    z = c - e
    z /= np.linalg.norm(z)
    x = np.cross(z, u)
    if np.linalg.norm(x) < 1e-9:
        x = np.cross(z, np.array([1.0, 0.0, 0.0]))
    x /= np.linalg.norm(x)
    y = np.cross(z, x)
    T = np.eye(4)
    T[:3, :3] = np.column_stack([x, y, z])
    T[:3, 3] = e
    return T


SIM_CAMERA_K = np.array([[905.0, 0.0, 645.0], [0.0, 902.0, 478.0], [0.0, 0.0, 1.0]])
"""The simulated camera's true intrinsics (1280 × 960, no distortion)."""
SIM_CAMERA_SIZE = (1280, 960)
SIM_VIEW = {"so101": ((-0.08, 0.0, 0.55), (0.11, 0.0, 0.19)), "koch": ((-0.1, 0.0, 0.5), (0.0, 0.0, 0.15))}
"""Where the simulated camera is (eye, looked-at point), base frame, m."""
SIM_MOUNT = {"so101": (0.0121, 0.0, -0.0981), "koch": (0.02, 0.0, -0.06)}
"""Where the simulated tag sits on the tip link (its face along the tip link's +z), m."""
SIM_TARGET_PLACE = {"so101": ((0.4, 0.0, 0.15), (0.0, -math.pi / 2, 0.0))}
"""Camera on the tool: where the fixed tag stands (xyz m, URDF rpy; upright, its face towards the arm), base frame."""
SIM_CAMERA_MOUNT = {"so101": ((0.0, 0.0, -0.03), (math.pi - 0.5, 0.0, 0.0))}
"""Camera on the tool: the camera's pose on the tip link (xyz m, URDF rpy): looking along the gripper, tilted."""


@dataclass(frozen=True, eq=False)
class SimImagesResult:
    """A simulated image session.

    Attributes:
        urdf: Nominal URDF.
        data: Session CSV (joints + image).
        calibration_images: ChArUco images for ``camera-calibrate``.
        truth: JSON with the hidden parameters, the camera and the mounting.
        tip_link: Link carrying the target.
        target: The target string.
        board: The calibration board string.
        arm: The true arm (its model's world is the true camera frame).
    """

    urdf: Path
    data: Path
    calibration_images: tuple[Path, ...]
    truth: Path
    tip_link: str
    target: str
    board: str
    arm: SimulatedKinematicArm


def _visible(
    T_cam_target: FloatArray, target: Target, K: FloatArray, size: tuple[int, int]
) -> NDArray[np.bool_]:
    """Which target poses a camera sees whole, facing it within 60°, 20 px inside the image, 0.15 m away."""
    return target_visible(T_cam_target, target.object_points(), target.front_normal(), K, size)


@dataclass(frozen=True)
class SimImagesRequest:
    """A tag session to render of a simulated arm with hidden errors (``kinematics simulate --kind tag``).

    Checked when built. Joint readings are quantised to ``ticks_per_turn`` ticks (0: exact); images have
    Gaussian pixel noise; poses are chosen among random ones where the camera sees the whole target: greedy
    I-optimal for the reprojection model (``kinematics plan --kind tag``,
    :func:`robocal.core.pose_plan.plan_image_poses`; with the camera on the tool greedy O1 of the tool point, as
    the tag plan measured no better there), or at random with ``plan=False``.

    Attributes:
        robot: ``so101`` or ``koch``.
        out_dir: Folder (created if its parent exists).
        poses: Images of the session (at least 3).
        seed: Seed of the hidden errors, the poses, the calibration boards and the pixel noise.
        target: The target on the tool (or fixed, ``camera_on_tool``): ``apriltag:…`` or ``charuco:…``.
        board: The ChArUco board of the calibration images.
        calibration_images: How many calibration images of ``board``.
        noise_grey: Gaussian pixel noise, grey levels.
        camera_on_tool: The camera is on the tip link and the tag stands fixed in front of the arm
            (:data:`SIM_CAMERA_MOUNT`, :data:`SIM_TARGET_PLACE`).
        plan: Plan the poses (else random ones the camera sees).
        ticks_per_turn: Encoder ticks per turn the joint readings are rounded to (0: exact).

    Raises:
        UsageError: An unknown robot or one without this set-up, fewer than 3 poses, a negative seed or tick
            count.
    """

    robot: str
    out_dir: str | os.PathLike[str]
    poses: int = 50
    seed: int = 0
    target: str = "apriltag:36h11:0:60"
    board: str = "charuco:7x5:30:22:4x4_50"
    calibration_images: int = 20
    noise_grey: float = 2.0
    camera_on_tool: bool = False
    plan: bool = True
    ticks_per_turn: int = 4096

    def __post_init__(self) -> None:
        from .fit import check_seed
        from .sim import SIM_ROBOTS, check_ticks

        robot, camera_on_tool = self.robot, self.camera_on_tool
        if robot not in SIM_ROBOTS:
            raise UsageError(f"unknown simulated robot {robot!r}; valid: {', '.join(SIM_ROBOTS)}")
        if robot not in (SIM_TARGET_PLACE if camera_on_tool else SIM_VIEW):
            where = SIM_TARGET_PLACE if camera_on_tool else SIM_VIEW
            setup = "with the camera on the tool " if camera_on_tool else ""
            raise UsageError(f"tag images {setup}are simulated for {', '.join(where)} only, not {robot!r}")
        if self.poses < 3:
            raise UsageError(f"--poses must be at least 3 for images, got {self.poses}")
        check_seed(self.seed)
        check_ticks(self.ticks_per_turn)


def simulate_images(request: SimImagesRequest) -> SimImagesResult:
    """Render the tag session of ``request``, seen by a simulated camera, and the camera's calibration images.

    Writes ``<robot>.urdf``, ``images/pose_NNN.png`` and ``tag.csv`` (joints + image), ``calibration/
    board_NN.png`` (a ChArUco board in front of the camera) and ``truth.json`` into the request's folder.

    Args:
        request: What to render (checked when it was built).

    Returns:
        The :class:`SimImagesResult`.

    Raises:
        CalibError: ``out_dir`` a file or in a missing folder, a bad target or board, too few poses the camera
            sees.
    """
    from .sim import SIM_ROBOTS, shipped_urdf, sim_out_folder

    r = request
    robot, poses, seed, target, board = r.robot, r.poses, r.seed, r.target, r.board
    camera_on_tool, noise_grey = r.camera_on_tool, r.noise_grey
    folder = sim_out_folder(r.out_dir)
    tgt = parse_target(target)
    brd = parse_target(board, "--board")
    spec = SIM_ROBOTS[robot]
    src = shipped_urdf(robot)
    urdf_bytes = src.read_bytes()
    chain = chain_from_urdf(UrdfDocument.from_bytes(urdf_bytes, str(src)).model(), tip_link=spec.tip_link)
    rng = np.random.default_rng(seed)
    if camera_on_tool:
        xyz, rpy = SIM_TARGET_PLACE[robot]
        T_world_base = np.asarray(np.linalg.inv(homogeneous(matrix_from_rpy_urdf(np.array(rpy)), xyz)), np.float64)
        xyz, rpy = SIM_CAMERA_MOUNT[robot]
        mount = homogeneous(matrix_from_rpy_urdf(np.array(rpy)), xyz)
        n_candidates = 100_000  # a camera on the wrist faces the tag in under 1 % of random poses
    else:
        eye, centre = SIM_VIEW[robot]
        T_world_base = np.asarray(np.linalg.inv(look_at(eye, centre)), dtype=np.float64)
        mount = np.eye(4)
        mount[:3, 3] = SIM_MOUNT[robot]
        n_candidates = 4000
    model = ErrorModel(chain, T_world_base=T_world_base, T_tip_tool=mount)
    arm = SimulatedKinematicArm(model, hidden_errors(model, rng), ticks_per_turn=r.ticks_per_turn)

    def cam_target(T_world_tool: FloatArray) -> FloatArray:
        return np.asarray(np.linalg.inv(T_world_tool), dtype=np.float64) if camera_on_tool else T_world_tool

    cand = arm.sample_q(n_candidates, rng)
    seen = cand[_visible(cam_target(model.tool_poses(cand, arm.x_true)), tgt, SIM_CAMERA_K, SIM_CAMERA_SIZE)]
    if seen.shape[0] < poses:
        raise UsageError(f"the simulated camera sees the target in only {seen.shape[0]} candidate poses")
    if r.plan and not camera_on_tool:
        nominal = ErrorModel(chain, T_world_base=T_world_base, T_tip_tool=mount)
        q = seen[plan_image_poses(nominal, seen, tgt.object_points(), SIM_CAMERA_K, poses).index]
    elif r.plan:  # a wrist camera: the tag plan gains nothing measurable here (docs/kinematics.md); greedy O1
        q = seen[plan_poses(ErrorModel(chain, T_tip_tool=mount), seen, poses)]
    else:
        q = seen[rng.permutation(seen.shape[0])[:poses]]
    T_true = model.tool_poses(q, arm.x_true)
    folder.mkdir(exist_ok=True)  # only now: nothing is made when the set-up fails
    (folder / "images").mkdir(exist_ok=True)
    names = []
    for i, T in enumerate(T_true):
        name = f"images/pose_{i + 1:03d}.png"
        write_image(
            folder / name,
            render(tgt, SIM_CAMERA_K, SIM_CAMERA_SIZE, cam_target(T), noise_grey=noise_grey, rng=rng),
        )
        names.append(name)
    (folder / "calibration").mkdir(exist_ok=True)
    calib = []
    from ...core.se3 import matrix_from_rotvec

    board_centre = np.array([brd.cols * brd.size_m / 2, brd.rows * brd.size_m / 2, 0.0])
    for k in range(r.calibration_images):  # tilted up to 40°, 0.3-0.5 m away, spread over the image
        R = matrix_from_rotvec([rng.uniform(-0.7, 0.7), rng.uniform(-0.7, 0.7), rng.uniform(-0.3, 0.3)])
        pixel = [rng.uniform(250, SIM_CAMERA_SIZE[0] - 250), rng.uniform(200, SIM_CAMERA_SIZE[1] - 200), 1.0]
        T = np.eye(4)
        T[:3, :3] = R
        T[:3, 3] = rng.uniform(0.3, 0.5) * np.linalg.solve(SIM_CAMERA_K, pixel) - R @ board_centre
        path = folder / "calibration" / f"board_{k + 1:02d}.png"
        write_image(path, render(brd, SIM_CAMERA_K, SIM_CAMERA_SIZE, T, noise_grey=noise_grey, rng=rng))
        calib.append(path)
    urdf_path = atomic_write_bytes(folder / f"{robot}.urdf", urdf_bytes)
    data_path = atomic_write_text(
        folder / "tag.csv", session_csv(arm.read(q), chain.joint_names, {"image": names})
    )
    truth = {
        "robot": robot,
        "seed": seed,
        "tip_link": spec.tip_link,
        "target": target,
        "board": board,
        "camera_K": SIM_CAMERA_K.tolist(),
        "camera_size": list(SIM_CAMERA_SIZE),
        "setup": "camera on the tool, target fixed" if camera_on_tool else "camera fixed, target on the tool",
        **(
            {"T_target_base": T_world_base.tolist(), "T_tip_camera_nominal": mount.tolist()}
            if camera_on_tool
            else {"T_cam_base": T_world_base.tolist(), "T_tip_target_nominal": mount.tolist()}
        ),
        "ticks_per_turn": arm.ticks_per_turn,
        "pixel_noise_grey": noise_grey,
        "hidden_parameters": {n: float(v) for n, v in zip(model.names, arm.x_true, strict=True)},
    }
    truth_path = atomic_write_text(folder / "truth.json", json.dumps(truth, indent=2) + "\n")
    return SimImagesResult(urdf_path, data_path, tuple(calib), truth_path, spec.tip_link, target, board, arm)
