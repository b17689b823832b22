"""``plan --kind tag`` with and without ``--prior`` against random images, on the simulated SO-101 and Koch.

``python benchmarks/run.py kinematics_tag_prior`` (env: TAG_PRIOR_SEEDS=5, TAG_PRIOR_REPS=3, TAG_PRIOR_IMAGES=30,10).

Per seed: an arm with hidden errors (1 mm, 0.5°, 2° σ), the fixed simulated camera, 2000 candidate poses where
it sees the whole 60 mm tag; three image sets: the I-optimal plan, the Bayesian one (``--prior``) and random
ones. Per set and noise draw: synthetic corners (the exact projection of the true arm plus 0.3 px), 4096-tick
joint readings, all images fitted (plain and with ``--prior``); the error of the target's centre against the
truth on 400 new poses the camera sees, mm. The docs table (docs/kinematics.md, "Camera sessions") is this run.
"""

from __future__ import annotations

import os

import numpy as np

from robocal.backends.sim.kinematic_arm import SimulatedKinematicArm, hidden_errors
from robocal.backends.vision import CameraIntrinsics, parse_target, solve_pnp
from robocal.core.chain import fk_chain
from robocal.core.kinematic_errors import ErrorModel
from robocal.core.kinematic_images import ImageObservations, ImageProblem, hand_eye
from robocal.core.pose_plan import plan_image_poses, target_visible
from robocal.formats.urdf import read_urdf
from robocal.formats.urdf_chain import chain_from_urdf
from robocal.workflows.kinematics.fit import PriorSigmas, fit
from robocal.workflows.kinematics.sim import SIM_ROBOTS, shipped_urdf
from robocal.workflows.kinematics.vision_sim import (
    SIM_CAMERA_K,
    SIM_CAMERA_SIZE,
    SIM_MOUNT,
    SIM_VIEW,
    look_at,
)

NOISE_PX = 0.3
K = SIM_CAMERA_K


def _session(
    robot: str, seeds: int, reps: int, n_images: int
) -> dict[tuple[str, str], list[tuple[float, float]]]:
    tgt = parse_target("apriltag:36h11:0:60")
    corners = tgt.object_points()
    cam = CameraIntrinsics(*SIM_CAMERA_SIZE, K, np.zeros(5))
    chain = chain_from_urdf(read_urdf(shipped_urdf(robot)), tip_link=SIM_ROBOTS[robot].tip_link)
    eye, centre = SIM_VIEW[robot]
    mount = np.eye(4)
    mount[:3, 3] = SIM_MOUNT[robot]
    nominal = ErrorModel(chain, T_world_base=np.linalg.inv(look_at(eye, centre)), T_tip_tool=mount)
    sig = PriorSigmas().model_sigmas(nominal, tool_free=True)

    def seen(arm: SimulatedKinematicArm, q: np.ndarray) -> np.ndarray:
        T = nominal.tool_poses(q, arm.x_true)
        return q[target_visible(T, corners, tgt.front_normal(), K, SIM_CAMERA_SIZE)]

    out: dict[tuple[str, str], list[tuple[float, float]]] = {}
    for seed in range(seeds):
        rng = np.random.default_rng(seed)
        arm = SimulatedKinematicArm(nominal, hidden_errors(nominal, rng))
        cand = seen(arm, arm.sample_q(4000, rng))[:2000]
        plans = {
            "planned": plan_image_poses(nominal, cand, corners, K, n_images).index,
            "planned --prior": plan_image_poses(nominal, cand, corners, K, n_images, prior_sigma=sig).index,
            "random": rng.permutation(cand.shape[0])[:n_images],
        }
        q_new = seen(arm, arm.sample_q(20000, np.random.default_rng(1000 + seed)))[:400]
        for name, idx in plans.items():
            q = cand[idx]
            T_true = nominal.tool_poses(q, arm.x_true)
            p = np.einsum("nij,kj->nki", T_true[:, :3, :3], corners) + T_true[:, None, :3, 3]
            for rep in range(reps):
                noise = np.random.default_rng(500 + 10 * seed + rep)  # the same noise for every image set
                px = p[..., :2] / p[..., 2:] * K[[0, 1], [0, 1]] + K[[0, 1], [2, 2]]
                px = px + noise.normal(0.0, NOISE_PX, px.shape)
                uv = (px - K[[0, 1], [2, 2]]) / K[[0, 1], [0, 1]]
                T_pnp = np.array([solve_pnp(corners, px[i], cam) for i in range(len(q))])
                q_read = arm.read(q)
                obs = ImageObservations(
                    q_read, np.repeat(np.arange(len(q)), len(corners)), np.tile(corners, (len(q), 1)),
                    uv.reshape(-1, 2), cam.focal_px, T_pnp, K,
                )  # fmt: skip
                X, Y = hand_eye(T_pnp, ErrorModel(chain).tool_poses(q_read))
                model = ErrorModel(chain, T_world_base=X, T_tip_tool=Y)
                problem = ImageProblem(model, obs, tuple(range(model.n_params)), np.zeros(model.n_params))
                for fit_name, prior in (("plain", None), ("--prior", PriorSigmas())):
                    result = fit(problem, prior=prior)
                    found, T_cb, T_tt = model.corrected(result.x)
                    T = T_cb @ fk_chain(found, arm.read(q_new)) @ T_tt
                    err = np.linalg.norm(T[:, :3, 3] - arm.true_points(q_new), axis=1) * 1e3
                    out.setdefault((name, fit_name), []).append((float(err.mean()), float(err.max())))
    return out


def main() -> None:
    seeds = int(os.environ.get("TAG_PRIOR_SEEDS", "5"))
    reps = int(os.environ.get("TAG_PRIOR_REPS", "3"))
    images = [int(v) for v in os.environ.get("TAG_PRIOR_IMAGES", "30,10").split(",")]
    print(f"seeds 0-{seeds - 1}, {reps} noise draws each; error of the target's centre on 400 new poses, mm")
    print("arm     images  images chosen     fit      mean (range)           max (avg)")
    for robot in ("so101", "koch"):
        for n in images:
            for (plan, fit_name), v in _session(robot, seeds, reps, n).items():
                a = np.array(v)
                print(
                    f"{robot:7s} {n:6d}  {plan:16s}  {fit_name:7s}  {a[:, 0].mean():.3f} "
                    f"({a[:, 0].min():.3f}-{a[:, 0].max():.3f})  {a[:, 1].mean():.3f}",
                    flush=True,
                )


if __name__ == "__main__":
    main()
