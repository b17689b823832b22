"""Dataset health job (``robocal dataset health``): robot profile, URDF and calibration files → the check → report.

Builds the check's expectations (:class:`robocal.dataset.health.HealthSetup`) from the robot profile (units from
LeRobot's norm modes, stop angles from its ``auto_calibration`` section, the follower's position gains as LeRobot
configures them), the URDF's masses (``--urdf``, else the robot's shipped URDF when it has masses) and the two
calibration files, runs :func:`robocal.dataset.health.dataset_health`, and writes the JSON report and a picture
beside it (``health.json`` → ``health.png``). Everything is checked before anything is written.
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from ...core.lerobot import RobotSpec
from ...errors import FileFormatError, JointMismatchError, UsageError

if TYPE_CHECKING:
    from ...backends.servo_ratings import PositionLoop
    from ...core.gravity import GravityModel
    from ...dataset._convention import ValueConvention
    from ...dataset.health import DatasetHealth, HealthSetup

__all__ = ["HealthOutcome", "HealthRequest", "evaluate_health", "follower_loop", "render_picture", "run_health"]

_SHIPPED_URDF = {"so100": "so101_new_calib.urdf", "so101": "so101_new_calib.urdf", "koch": "koch.urdf"}


@dataclass(frozen=True)
class HealthRequest:
    """One dataset health check.

    Attributes:
        root: Dataset root (LeRobot v3, ``action`` = leader, ``observation.state`` = follower).
        report: JSON report to write; the picture goes beside it with the suffix ``.png``.
        robot: Robot profile (``so101_follower``, ``koch_follower``, ...); default the dataset's ``robot_type``.
        urdf: URDF with masses for the sag model; default the robot's shipped URDF (if it has masses).
        leader_calibration: The leader's calibration file (with ``follower_calibration``: values in degrees).
        follower_calibration: The follower's calibration file.
        use_degrees: Whether arm joints were recorded in degrees; ``None``: the robot's LeRobot default.
    """

    root: Path
    report: Path
    robot: str | None = None
    urdf: Path | None = None
    leader_calibration: Path | None = None
    follower_calibration: Path | None = None
    use_degrees: bool | None = None


@dataclass(frozen=True, eq=False)
class HealthOutcome:
    """What :func:`run_health` did.

    Attributes:
        result: The check's result.
        report: The JSON written (as a dict).
        report_path: Where it was written.
        picture_path: The picture beside it.
    """

    result: DatasetHealth
    report: dict[str, Any]
    report_path: Path
    picture_path: Path


def follower_loop(spec: RobotSpec) -> tuple[dict[str, float], dict[str, bool], dict[str, float]]:
    """Per motor: the follower's position stiffness (N·m/rad), goal clamped to its limits, largest sag (degrees).

    The largest sag is what its stall torque holds, ``τ_stall / kp``; missing where the stiffness is not known.

    The stiffness is the servo's position loop (its vendor's model, ``backends/<vendor>/gains.py``) at the gains
    LeRobot writes (the profile's ``position_gains``), else at the servo's factory gains; ``inf`` (no sag) for a
    model robocal has no rating or factory table for. A motor's goal is clamped to the position limits (LeRobot's
    recorded range) when the mode LeRobot runs it in is one of its vendor's ``goal_limit_modes`` (Feetech position
    mode; not the Dynamixels' extended or current-based position) and it is not a full-turn motor (limits
    0..4095).
    """
    from ...backends import load_backend
    from ...backends.servo_ratings import RATINGS

    vendor = spec.vendor_spec
    loop: PositionLoop | None = None if vendor.position_loop is None else load_backend(vendor.position_loop)
    kp, limited, sag_limit = {}, {}, {}
    for m in spec.motors:
        kp[m.name] = math.inf
        if loop is not None:
            try:
                p, _, d = m.position_gains or loop.factory_gains(m.model)
                kp[m.name] = loop.gains_nm_rad(m.model, p, d)[0]
                sag_limit[m.name] = math.degrees(RATINGS[m.model].stall_torque_nm / kp[m.name])
            except (KeyError, ZeroDivisionError):  # no rating or factory table for the model, or no gain: no sag
                kp[m.name] = math.inf
        limited[m.name] = spec.run_mode(m) in vendor.goal_limit_modes and m.name not in spec.full_turn
    return kp, limited, sag_limit


def _gravity(request: HealthRequest, robot: str) -> tuple[GravityModel | None, str | None]:
    from ...formats.urdf_gravity import gravity_model_if_any

    if request.urdf is not None:
        return gravity_model_if_any(request.urdf), str(request.urdf)
    stem = next((v for k, v in _SHIPPED_URDF.items() if robot.startswith(k)), None)
    if stem is None:
        return None, None
    from importlib import resources

    path = Path(str(resources.files("robocal") / "data" / stem))
    return gravity_model_if_any(path), str(path)


def _check_calibration(what: str, path: Path, conv: ValueConvention, joints: list[str]) -> None:
    """A LeRobot calibration (current or legacy JSON) with a motor for every joint of the dataset.

    Raises:
        FileFormatError: Another format (a URDF or a joint map reads as a calibration, in no arm's ticks).
        JointMismatchError: A joint of the dataset the file has no motor for.
    """
    from ...dataset.lerobot import LegacyConvention, LeRobotConvention

    if not isinstance(conv, LeRobotConvention | LegacyConvention):
        raise FileFormatError(
            f"{what} {path}: not a LeRobot calibration file; the check reads each arm's LeRobot calibration JSON "
            "(id, drive_mode, homing_offset, range_min, range_max per motor)"
        )
    names = set(conv.joint_names)
    missing = [j for j in joints if j not in names]
    if missing:
        raise JointMismatchError(
            f"{what} {path}: no motor named {', '.join(missing)} (the dataset's joints: {', '.join(joints)})"
        )


def _setup(request: HealthRequest) -> tuple[HealthSetup, str, str | None]:
    from ...dataset import read_layout
    from ...dataset.health import HealthSetup
    from ...dataset.lerobot import load_convention, motor_family_for_robot, preset_modes
    from ...formats.profiles import builtin_lerobot_profiles, load_profile

    arms = [p.name for p in builtin_lerobot_profiles()]
    if request.robot is not None and not request.robot.strip():  # not "use info.json's", said so
        raise UsageError(
            f"--robot {request.robot!r} is empty: name a built-in LeRobot arm ({', '.join(arms)}), or leave "
            "--robot out to use meta/info.json's robot_type"
        )
    if (request.leader_calibration is None) != (request.follower_calibration is None):
        raise UsageError("--leader-calibration and --follower-calibration go together (one per arm)")
    layout = read_layout(request.root)
    robot = request.robot or layout.robot_type
    if robot is None:
        raise UsageError(
            f"dataset {request.root}: meta/info.json names no robot_type; name the arm with --robot"
        )
    if not request.robot and robot not in arms:  # never a file named by the dataset
        raise UsageError(
            f"dataset {request.root}: meta/info.json robot_type {robot!r} is not a built-in LeRobot arm "
            f"({', '.join(arms)}); name the arm with --robot"
        )
    profile = load_profile(robot)
    if robot not in arms:  # a profile file or another robot: the modes and motor family are a LeRobot arm's
        raise UsageError(f"--robot {robot!r}: dataset health needs a built-in LeRobot arm ({', '.join(arms)})")
    joints = list(layout.vector_feature("observation.state").joint_names)
    if not {j.name for j in profile.joints}.intersection(joints):
        raise JointMismatchError(
            f"dataset {request.root}: observation.state names {', '.join(joints)}, none of them a joint of {robot} "
            f"({', '.join(j.name for j in profile.joints)}); name the dataset's arm with --robot"
        )
    modes = preset_modes(robot, joints, request.use_degrees)
    auto = {j.name: j for j in profile.auto.joints} if profile.auto is not None else {}
    loop_kp, loop_limited, sag_limit = (
        follower_loop(RobotSpec.from_profile(profile)) if profile.lerobot is not None else ({}, {}, {})
    )
    units, upd, stops, kp, limited = {}, {}, {}, {}, {}
    for j in joints:
        a = auto.get(j)
        stop = (a.lower_deg, a.upper_deg) if a is not None and a.stops == "both" else None
        stops[j] = (
            None if stop is None or stop[0] is None or stop[1] is None else (float(stop[0]), float(stop[1]))
        )
        mode = modes.get(j, "degrees")
        units[j] = mode
        span = None if stops[j] is None else stops[j][1] - stops[j][0]  # type: ignore[index]
        upd[j] = (
            1.0
            if mode == "degrees"
            else (math.nan if not span else (100.0 if mode == "range_0_100" else 200.0) / span)
        )
        kp[j] = loop_kp.get(j, math.inf)
        limited[j] = loop_limited.get(j, False)
    gravity, urdf = _gravity(request, robot)
    if request.urdf is not None and gravity is not None and not set(joints) & set(gravity.joint_names):
        raise JointMismatchError(
            f"--urdf {request.urdf}: none of the dataset's joints ({', '.join(joints)}) is a joint of it; the sag "
            "model needs the arm's URDF"
        )
    leader = follower = None
    if request.leader_calibration is not None and request.follower_calibration is not None:
        family = motor_family_for_robot(robot)
        leader = load_convention(
            request.leader_calibration,
            joint_names=joints,
            modes=modes,
            family=family,
            what="--leader-calibration",
        )
        follower = load_convention(
            request.follower_calibration,
            joint_names=joints,
            modes=modes,
            family=family,
            what="--follower-calibration",
        )
        for what, path, conv in (
            ("--leader-calibration", request.leader_calibration, leader),
            ("--follower-calibration", request.follower_calibration, follower),
        ):
            _check_calibration(what, path, conv, joints)
    return HealthSetup(units, upd, stops, kp, gravity, leader, follower, limited, sag_limit), robot, urdf


def render_picture(result: DatasetHealth) -> bytes:
    """Per joint: the residual against the follower's pose, the model band and the frames used (PNG bytes)."""
    import io

    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    n = len(result.joints)
    cols = 3
    rows = max(1, math.ceil(n / cols))
    fig, axes = plt.subplots(rows, cols, figsize=(5.2 * cols, 3.6 * rows), squeeze=False)
    colours = {"ok": "tab:green", "unobservable": "tab:gray", "suspect": "tab:orange", "offset": "tab:red"}
    for k, (h, units, _upd, _eps, _notes) in enumerate(result.joints):
        ax = axes[k // cols][k % cols]
        pose, res = result.pose[:, k], h.residual
        fin = np.isfinite(res)
        ax.plot(pose[fin], res[fin], ".", ms=1.5, color="0.8", label="all frames")
        slow = fin & (h.used == 1.0)
        ax.plot(pose[slow], res[slow], ".", ms=2, color="tab:blue", label="slow frames (band fit)")
        end = fin & (h.used == 2.0)
        ax.plot(pose[end], res[end], ".", ms=3, color="tab:red", label="range-end frames")
        ax.axhspan(-h.band, h.band, color="tab:green", alpha=0.15, label=f"model band ±{h.band:.2f}")
        unit = "°" if units == "degrees" else f" ({units})"
        head = f"{h.name}: {h.status}"
        if h.offset is not None and h.status in ("offset", "ok"):
            head += f" {h.offset:+.2f}{unit}" if h.status == "offset" else f", offset {h.offset:+.2f}{unit}"
            if h.ci is not None:
                head += f" [{h.ci[0]:+.2f}, {h.ci[1]:+.2f}]"
        ax.set_title(head, color=colours.get(h.status, "black"), fontsize=10)
        ax.set_xlabel(f"follower pose{unit}")
        ax.set_ylabel(f"action(t−1) − state(t) − sag{unit}")
        lim = max(3.0 * h.band, float(np.nanpercentile(np.abs(res[fin]), 99.5)) if fin.any() else 1.0)
        ax.set_ylim(-1.2 * lim, 1.2 * lim)
        if k == 0:
            ax.legend(fontsize=7, loc="upper left", markerscale=3)
    for k in range(n, rows * cols):
        axes[k // cols][k % cols].axis("off")
    fig.suptitle(
        f"{result.root.name}: {result.frames} frames, {result.episodes} episodes "
        f"(offset = follower calibration − leader calibration)",
        fontsize=11,
    )
    fig.tight_layout()
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=80)
    plt.close(fig)
    return buf.getvalue()


def run_health(request: HealthRequest) -> HealthOutcome:
    """Check a dataset's calibration health and write the report and its picture (see the module docstring).

    Raises:
        UsageError, FileFormatError, JointMismatchError: Bad input (nothing is written).
        FileWriteError: The report or picture cannot be written.
    """
    from ...fileio import atomic_write_bytes, atomic_write_text, check_output_path
    from ...formats.profiles import profile_file

    report_path = Path(request.report)
    if report_path.suffix.lower() != ".json":
        raise UsageError(
            f"--report {report_path}: expected a .json file (the picture goes beside it as .png)"
        )
    picture_path = report_path.with_suffix(".png")
    inputs = {
        "the dataset": request.root,
        "--urdf": request.urdf,
        "--leader-calibration": request.leader_calibration,
        "--follower-calibration": request.follower_calibration,
        "--robot": profile_file(request.robot),
    }
    check_output_path(report_path, "--report", inputs=inputs)
    # the picture through a link to the report would replace the report just written
    check_output_path(picture_path, "the report's picture", inputs={**inputs, "--report": report_path})
    result, report = evaluate_health(request)
    picture = render_picture(result)
    atomic_write_text(report_path, json.dumps(report, indent=2) + "\n")
    atomic_write_bytes(picture_path, picture)
    return HealthOutcome(result, report, report_path, picture_path)


def evaluate_health(request: HealthRequest) -> tuple[DatasetHealth, dict[str, Any]]:
    """The check and its JSON report, nothing written (``request.report`` is not used).

    Raises:
        UsageError, FileFormatError, JointMismatchError: Bad input.
    """
    from ...dataset.health import dataset_health, health_json

    setup, robot, urdf = _setup(request)
    result = dataset_health(request.root, setup)
    report = health_json(result)
    report["robot"] = robot
    report["model"] = {
        "urdf": urdf if setup.gravity is not None else None,
        "sag": "gravity torque of the URDF's masses over the follower's position gain"
        if setup.gravity is not None
        else "no URDF masses: per joint with stops, c0 + c1·sin q + c2·cos q fitted to the slow frames",
        "kp_nm_rad": {j: (round(v, 4) if math.isfinite(v) else None) for j, v in setup.kp_nm_rad.items()},
        "calibration_files": setup.leader is not None,
    }
    return result, report
