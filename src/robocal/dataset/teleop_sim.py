"""Simulated teleoperation datasets with their truth, for the calibration health check and its benchmark.

:func:`generate_teleop_datasets` simulates sessions (:mod:`robocal.backends.sim.teleop`: a human-like leader, a
follower servo arm with LeRobot's gains, gravity, friction, backlash, stops, encoder ticks; injected offsets,
slips, clipping, a mirrored sign) and writes each as a LeRobot v3 dataset root (``meta/info.json``,
``data/chunk-000/file-000.parquet`` with one row group per episode, ``meta/episodes``, ``meta/tasks.parquet``,
``meta/stats.json``), the layout every ``robocal dataset`` command reads, with ``ROOT.truth.json`` beside it.

The SO-101's gravity comes from the shipped ``so101_new_calib.urdf``'s masses (the whole arm's pose each frame);
Koch's from per-joint amplitudes (its URDF has no masses). Values: degrees for the arm joints when
``use_degrees`` (LeRobot's SO default), else ``range_m100_100`` (Koch's default); the gripper ``range_0_100``;
a range mode maps the profile's stops to ±100 (0..100), as a calibration recorded at the stops does.
"""

from __future__ import annotations

import json
import math
from collections.abc import Sequence
from dataclasses import asdict
from pathlib import Path
from typing import Any

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq

from ..backends.sim.teleop import TELEOP_ARMS, TeleopArm, TeleopFaults, TeleopSession, simulate_sessions
from ..backends.sim.teleop_plant import GravityFn
from ..core.arrays import FloatArray
from ..errors import UsageError
from ._generate import (
    add_stats,
    data_schema,
    episode_row,
    episode_table,
    info_document,
    merged_stats,
    write_tasks,
)
from ._stats import StatAccumulator

__all__ = ["arm_gravity", "generate_teleop_datasets", "to_values", "write_teleop_dataset"]


def arm_gravity(arm: TeleopArm) -> GravityFn | None:
    """The gravity of ``arm`` from its shipped URDF's masses (SO-101), or None (Koch: per-joint amplitudes)."""
    if arm.name != "so101":
        return None
    from ..core.gravity import gravity_torques
    from ..formats.urdf_gravity import gravity_model_from_urdf

    urdf = Path(__file__).resolve().parent.parent / "data" / "so101_new_calib.urdf"
    model = gravity_model_from_urdf(urdf)
    cols = [model.joint_names.index(n) for n in arm.joints]

    def gravity(q: FloatArray) -> FloatArray:
        qm = np.zeros((q.shape[0], len(model.joint_names)))
        qm[:, cols] = q
        out: FloatArray = gravity_torques(model, qm)[:, cols]
        return out

    return gravity


def to_values(arm: TeleopArm, deg: FloatArray, use_degrees: bool) -> FloatArray:
    """Degrees ``(..., J)`` → the dataset's values (degrees, or a range mode scaled on the profile's stops).

    A range mode's value is clamped to its ends, as LeRobot's normalisation does (a session simulated with these
    modes already is: :func:`~robocal.backends.sim.teleop.simulate_sessions`).
    """
    modes = arm.modes if use_degrees else arm.range_modes
    out = np.array(deg, dtype=np.float64)
    for j, mode in enumerate(modes):
        lo, hi = arm.stop_lo_deg[j], arm.stop_hi_deg[j]
        if not math.isfinite(lo):
            lo, hi = -180.0, 180.0
        if mode == "range_0_100":
            out[..., j] = np.clip((deg[..., j] - lo) / (hi - lo) * 100.0, 0.0, 100.0)
        elif mode == "range_m100_100":
            out[..., j] = np.clip((deg[..., j] - 0.5 * (lo + hi)) / (0.5 * (hi - lo)) * 100.0, -100.0, 100.0)
    return out


def write_teleop_dataset(session: TeleopSession, root: str | Path, *, use_degrees: bool = True) -> Path:
    """Write one session as a LeRobot v3 dataset at ``root`` and its truth at ``ROOT.truth.json``.

    Returns:
        The truth file's path.

    Raises:
        UsageError: ``root`` exists.
    """
    r = Path(root)
    if r.exists():
        raise UsageError(f"simulated dataset {r}: already exists")
    arm = session.arm
    d = len(arm.joints)
    schema = data_schema(d)
    (r / "meta" / "episodes" / "chunk-000").mkdir(parents=True)
    (r / "data" / "chunk-000").mkdir(parents=True)
    state = to_values(arm, session.state_deg, use_degrees).astype(np.float32)
    action = to_values(arm, session.action_deg, use_degrees).astype(np.float32)
    episodes, frames, _ = state.shape
    rows: list[dict[str, Any]] = []
    accs: list[dict[str, StatAccumulator]] = []
    index = 0
    with pq.ParquetWriter(r / "data/chunk-000/file-000.parquet", schema=schema, compression="snappy") as w:
        for e in range(episodes):
            ts = (np.arange(frames) / session.fps).astype(np.float32)
            w.write_table(episode_table(schema, state[e], action[e], ts, e, index), row_group_size=frames)
            acc = {
                "observation.state": StatAccumulator.of(state[e].astype(np.float64)),
                "action": StatAccumulator.of(action[e].astype(np.float64)),
            }
            accs.append(acc)
            row = episode_row(e, "teleoperate", frames, 0, index)
            add_stats(row, acc)
            rows.append(row)
            index += frames
    pq.write_table(pa.Table.from_pylist(rows), r / "meta/episodes/chunk-000/file-000.parquet")
    write_tasks(r, "teleoperate")
    stats = merged_stats(accs, ("observation.state", "action"))
    (r / "meta" / "stats.json").write_text(json.dumps(stats, indent=2))
    info = info_document(
        arm.joints, ("action", "observation.state"), arm.robot_type, episodes, index, int(session.fps)
    )
    (r / "meta" / "info.json").write_text(json.dumps(info, indent=2))
    truth = {
        "robot": arm.name,
        "seed": session.seed,
        "use_degrees": use_degrees,
        "faults": asdict(session.faults),
        "joints": {
            name: {
                k: (v if not isinstance(v, float) or math.isfinite(v) else None) for k, v in asdict(t).items()
            }
            for name, t in session.truth.items()
        },
    }
    out = r.with_name(r.name + ".truth.json")
    out.write_text(json.dumps(truth, indent=2))
    return out


def generate_teleop_datasets(
    folder: str | Path,
    robot: str,
    seeds: Sequence[int],
    faults: Sequence[TeleopFaults],
    *,
    use_degrees: bool = True,
    episodes: int = 6,
    episode_s: float = 15.0,
    p_end: float = 0.35,
    calibration_files: bool = False,
    goal_limits: bool = True,
) -> list[Path]:
    """Simulate and write one dataset per seed as ``folder/<robot>-<seed>`` (+ ``.truth.json``).

    Args:
        folder: Where the roots go (created).
        robot: ``so101`` or ``koch``.
        seeds: One seed per dataset.
        faults: One fault set per dataset.
        use_degrees: Arm joints in degrees (else ``range_m100_100``).
        episodes: Episodes per dataset.
        episode_s: Seconds per episode (30 fps).
        p_end: Chance per episode and joint of a visit to (or near) a range end.
        calibration_files: Also write the two arms' LeRobot calibrations that make the injected offset,
            ``ROOT.leader.json`` and ``ROOT.follower.json`` (:mod:`.teleop_calibration`; degrees only).
        goal_limits: The follower's servo clamps its goal to its recorded range as a real SO-101's does
            (:func:`~robocal.backends.sim.teleop.simulate_sessions`).

    Returns:
        The dataset roots.

    Raises:
        UsageError: Unknown robot, ``seeds`` and ``faults`` differ in length, or calibration files without
            degrees.
    """
    if robot not in TELEOP_ARMS:
        raise UsageError(f"simulated teleoperation: robot {robot!r}; expected {', '.join(TELEOP_ARMS)}")
    if len(seeds) != len(faults):
        raise UsageError("simulated teleoperation: one fault set per seed")
    if calibration_files and not use_degrees:
        raise UsageError("simulated teleoperation: calibration files go with degrees (use_degrees)")
    arm = TELEOP_ARMS[robot]
    sessions = simulate_sessions(
        arm,
        list(seeds),
        list(faults),
        gravity=arm_gravity(arm),
        episodes=episodes,
        episode_s=episode_s,
        p_end=p_end,
        modes=arm.modes if use_degrees else arm.range_modes,
        goal_limits=goal_limits,
    )
    base = Path(folder)
    base.mkdir(parents=True, exist_ok=True)
    roots = []
    for s in sessions:
        root = base / f"{robot}-{s.seed}"
        write_teleop_dataset(s, root, use_degrees=use_degrees)
        if calibration_files:
            from .teleop_calibration import write_calibration_pair

            write_calibration_pair(s, root)
        roots.append(root)
    return roots
